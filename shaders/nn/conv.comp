#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
// Direct convolution over video [B, Cin, F, H, W] (contiguous) with weights [Cout, Cin, KT, KH, KW]:
// Conv2d per frame (KT = 1) and the causal Conv3d of CogVideoX (KT > 1: the time axis is preceded by
// `prefix` frames taken from a cache tensor [B, Cin, prefix, H, W] or, without one, copies of frame 0).
// Spatial zero padding pad_top/pad_left; bottom/right padding is implied by Ho/Wo. fp32 accumulation.
//
// Register blocking: one invocation computes CO_R output channels x PX_R neighbouring output pixels of
// one row. The input row segment for a (ci, kt, kh) is loaded once and reused for all KW taps and CO_R
// channels; weights are indexed by the workgroup only (uniform), so every lane reads the same address.
#include "bf16.glsl"

layout(local_size_x = 64) in;
layout(constant_id = 0) const uint KT = 1;
layout(constant_id = 1) const uint KH = 3;
layout(constant_id = 2) const uint KW = 3;
layout(constant_id = 3) const uint STRIDE = 1;
layout(constant_id = 4) const uint WDT = 0;  // weight storage: 0 f32, 1 f16, 2 bf16 (read as packed uints)

const uint CO_R = 8;
const uint PX_R = 4;
const uint SPAN = (PX_R - 1) * STRIDE + KW;  // input columns one row of the block touches

layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) readonly buffer Cache { float cache[]; };
layout(std430, binding = 2) readonly buffer Wt { uint wt[]; };
layout(std430, binding = 3) readonly buffer Bias { uint bias[]; };  // same storage dtype as the weights
layout(std430, binding = 4) writeonly buffer Y { float y[]; };

layout(push_constant) uniform Push {
  uint cin, cout, frames, h, w, ho, wo;
  int pad_top, pad_left;
  uint prefix;      // frames prepended on the time axis (KT - 1 for causal convs, else 0)
  uint use_cache;   // 1: prefix frames come from `cache`; 0: they replicate input frame 0
  uint has_bias;
  uint tiles_w;     // ceil(wo / PX_R)
  uint frames_out;
  uint ys_b, ys_c, ys_f, ys_h;  // output strides (elements); the column stride is ys_w
  uint ys_w;
} p;

float unpack_at(uint word, uint e) {
  if (WDT == 1) return unpackHalf2x16(word)[e & 1u];
  return (e & 1u) == 0u ? bf16_lo(word) : bf16_hi(word);
}
float load_w(uint e) {
  if (WDT == 0) return uintBitsToFloat(wt[e]);
  return unpack_at(wt[e >> 1], e);
}
float load_bias(uint e) {
  if (WDT == 0) return uintBitsToFloat(bias[e]);
  return unpack_at(bias[e >> 1], e);
}

void main() {
  uint tile = gl_GlobalInvocationID.x;
  if (tile >= p.ho * p.tiles_w) return;
  uint oh = tile / p.tiles_w;
  uint ow0 = (tile % p.tiles_w) * PX_R;
  uint co0 = gl_WorkGroupID.y * CO_R;
  uint b = gl_WorkGroupID.z / p.frames_out;
  uint fo = gl_WorkGroupID.z % p.frames_out;
  uint hw = p.h * p.w;
  uint taps = KT * KH * KW;

  float acc[CO_R][PX_R];
  [[unroll]] for (uint c = 0; c < CO_R; ++c)
    [[unroll]] for (uint q = 0; q < PX_R; ++q) acc[c][q] = 0.0;

  // Weight rows of this workgroup's channels, clamped so a partial channel block reads in bounds.
  uint wrow[CO_R];
  [[unroll]] for (uint c = 0; c < CO_R; ++c) wrow[c] = min(co0 + c, p.cout - 1) * p.cin * taps;

  for (uint kt = 0; kt < KT; ++kt) {
    uint tp = fo + kt;  // frame index on the padded time axis
    bool from_cache = tp < p.prefix && p.use_cache != 0;
    uint frame = tp < p.prefix ? (from_cache ? tp : 0) : tp - p.prefix;
    uint fstride = from_cache ? p.prefix : p.frames;
    for (uint ci = 0; ci < p.cin; ++ci) {
      uint plane = ((b * p.cin + ci) * fstride + frame) * hw;
      uint wbase = ci * taps + kt * KH * KW;
      [[unroll]] for (uint kh = 0; kh < KH; ++kh) {
        int ih = int(oh * STRIDE) - p.pad_top + int(kh);
        if (ih < 0 || ih >= int(p.h)) continue;
        uint row = plane + uint(ih) * p.w;
        float xv[SPAN];
        [[unroll]] for (uint j = 0; j < SPAN; ++j) {
          int iw = int(ow0 * STRIDE) - p.pad_left + int(j);
          bool inside = iw >= 0 && iw < int(p.w);
          uint idx = row + uint(max(iw, 0));
          float v = from_cache ? cache[idx] : x[idx];
          xv[j] = inside ? v : 0.0;
        }
        [[unroll]] for (uint kw = 0; kw < KW; ++kw) {
          [[unroll]] for (uint c = 0; c < CO_R; ++c) {
            float wv = load_w(wrow[c] + wbase + kh * KW + kw);
            [[unroll]] for (uint q = 0; q < PX_R; ++q) acc[c][q] = fma(wv, xv[q * STRIDE + kw], acc[c][q]);
          }
        }
      }
    }
  }

  uint ybase = b * p.ys_b + fo * p.ys_f + oh * p.ys_h;
  [[unroll]] for (uint c = 0; c < CO_R; ++c) {
    uint co = co0 + c;
    if (co >= p.cout) break;
    float bv = p.has_bias != 0 ? load_bias(co) : 0.0;
    [[unroll]] for (uint q = 0; q < PX_R; ++q) {
      uint ow = ow0 + q;
      if (ow < p.wo) y[ybase + co * p.ys_c + ow * p.ys_w] = acc[c][q] + bv;
    }
  }
}
