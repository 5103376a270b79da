#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_ballot : require
// Direct convolution over video [B, Cin, F, H, W] (contiguous) with weights [Cout, Cin, KT, KH, KW]:
// Conv2d per frame (KT = 1) and the causal Conv3d of CogVideoX (KT > 1).
//
// Time axis: output frame fo reads padded frames tp = fo .. fo + KT - 1, where the padded axis is
// [prefix frames ; the input]. One dispatch reads ONE source tensor `src`: padded frame tp is src frame
// max(tp - src_shift, 0), so with src = x and src_shift = prefix the prefix replicates frame 0 (first
// frame batch). With a cache, the host splits the first `prefix` output frames into a pass over the cache
// taps (tap_mode 1, src = cache, shift 0, stores the partial sum) and a pass over the input taps
// (tap_mode 2, src = x, resumes from that partial sum): the taps are summed in the same order either way,
// so a clip run in frame batches gives bit-identical results to the whole clip.
// Spatial zero padding pad_top/pad_left; bottom/right padding is implied by Ho/Wo. fp32 accumulation.
//
// Register blocking (an implicit GEMM with the reduction over ci, kt, kh, kw): one invocation computes
// CO_R output channels x PX_R neighbouring output pixels of one row. Per (ci, kt, kh) the input row
// segment is fetched once from a texel buffer (cheaper per load than a storage buffer on lavapipe) and
// reused for all KW taps and CO_R channels. The CO_R * KW weights of that step are the same for every
// lane: with BCAST the 8 lanes of a subgroup each fetch a different one and subgroupBroadcast hands them
// round (lavapipe runs loads per lane, so this is 8x fewer loads); without it every lane loads them
// (GPUs broadcast uniform loads in hardware).
#include "bf16.glsl"

layout(local_size_x = 64) in;
layout(constant_id = 0) const uint KT = 1;
layout(constant_id = 1) const uint KH = 3;
layout(constant_id = 2) const uint KW = 3;
layout(constant_id = 3) const uint STRIDE = 1;
layout(constant_id = 4) const uint WDT = 0;      // weight storage: 0 f32, 1 f16, 2 bf16
layout(constant_id = 5) const bool BCAST = true;
layout(constant_id = 6) const uint CO_R = 16;    // output channels per invocation
layout(constant_id = 7) const uint PX_R = 16;    // output pixels (one row) per invocation
// UPSAMPLE: the convolution reads the nearest x2 spatial upsampling of src (CogVideoXUpsample3D fused:
// the 4x larger upsampled tensor is never stored); the frame map of its time upsampling is `time_map`.
layout(constant_id = 8) const bool UPSAMPLE = false;
const uint UP = UPSAMPLE ? 2 : 1;

const uint SPAN = (PX_R - 1) * STRIDE + KW;  // input columns one row of the block touches
const uint NW = CO_R * KW;                   // weights per (ci, kt, kh) step
const uint NG = (NW + 7) / 8;                // fetches of 8 weights for them

layout(binding = 0) uniform samplerBuffer src;   // R32_SFLOAT
layout(binding = 1) uniform usamplerBuffer wt;   // R32_UINT (f32) or R16_UINT (f16, bf16)
layout(std430, binding = 2) readonly buffer Bias { uint bias[]; };  // the weights' storage dtype
layout(std430, binding = 3) buffer Y { float y[]; };

layout(push_constant) uniform Push {
  uint cin, cout, src_frames, h, w, ho, wo;
  int pad_top, pad_left;
  uint prefix;      // padded frames before the input (KT - 1 for causal convs, else 0)
  uint src_shift;   // padded frame tp reads src frame max(tp - src_shift, 0)
  uint tap_mode;    // 0: all taps; 1: only taps with tp < prefix; 2: only tp >= prefix, resuming from y
  uint has_bias;
  uint tiles_w;     // ceil(wo / PX_R)
  uint frames;      // output frames in this dispatch, from fo_begin
  uint fo_begin;
  uint ys_b, ys_c, ys_f, ys_h, ys_w;  // output strides (elements)
  uint time_map;    // KT = 1 only: output frame -> src frame. 0: same; 1: 0 | 1+(t-1)/2; 2: t/2
} p;

float load_w(uint e) {
  uint u = texelFetch(wt, int(e)).x;
  if (WDT == 0) return uintBitsToFloat(u);
  if (WDT == 1) return unpackHalf2x16(u).x;
  return uintBitsToFloat(u << 16);
}
float load_bias(uint e) {
  if (WDT == 0) return uintBitsToFloat(bias[e]);
  uint word = bias[e >> 1];
  if (WDT == 1) return unpackHalf2x16(word)[e & 1u];
  return (e & 1u) == 0u ? bf16_lo(word) : bf16_hi(word);
}

float acc[CO_R][PX_R];

void main() {
  // No early return: every lane takes part in the subgroup broadcasts. Lanes past the end work on a
  // clamped tile and do not store.
  uint tiles = p.ho * p.tiles_w;
  uint tile_raw = gl_GlobalInvocationID.x;
  uint tile = min(tile_raw, tiles - 1);
  uint oh = tile / p.tiles_w;
  uint ow0 = (tile % p.tiles_w) * PX_R;
  uint co0 = gl_WorkGroupID.y * CO_R;
  uint b = gl_WorkGroupID.z / p.frames;
  uint fo = p.fo_begin + gl_WorkGroupID.z % p.frames;
  uint hw = p.h * p.w;
  uint taps = KT * KH * KW;
  uint ybase = b * p.ys_b + fo * p.ys_f + oh * p.ys_h;
  bool store = tile_raw < tiles;

  [[unroll]] for (uint c = 0; c < CO_R; ++c)
    [[unroll]] for (uint q = 0; q < PX_R; ++q) acc[c][q] = 0.0;
  if (p.tap_mode == 2) {  // resume from the partial sums of the cache pass (uniform branch)
    [[unroll]] for (uint c = 0; c < CO_R; ++c) {
      uint yc = ybase + min(co0 + c, p.cout - 1) * p.ys_c;
      [[unroll]] for (uint q = 0; q < PX_R; ++q) acc[c][q] = y[yc + min(ow0 + q, p.wo - 1) * p.ys_w];
    }
  }

  // With BCAST, lane l fetches weight n = 8g + l of each step: channel n / KW, tap n % KW. Without it,
  // channel c reads its own row. Channels past Cout read the last row (in bounds) and are not stored.
  uint lane = gl_SubgroupInvocationID % 8u;
  uint woff[NG];
  [[unroll]] for (uint g = 0; g < NG; ++g) {
    uint n = min(g * 8u + lane, NW - 1);
    woff[g] = min(co0 + n / KW, p.cout - 1) * p.cin * taps + n % KW;
  }
  uint wrow[CO_R];
  [[unroll]] for (uint c = 0; c < CO_R; ++c) wrow[c] = min(co0 + c, p.cout - 1) * p.cin * taps;

  // Input columns of the block (clamped) and whether they are inside the image.
  int col[SPAN];
  bool col_ok[SPAN];
  [[unroll]] for (uint j = 0; j < SPAN; ++j) {
    int iw = int(ow0 * STRIDE) - p.pad_left + int(j);
    col_ok[j] = iw >= 0 && iw < int(UP * p.w);
    col[j] = clamp(iw, 0, int(UP * p.w) - 1) / int(UP);
  }

  for (uint kt = 0; kt < KT; ++kt) {
    uint tp = fo + kt;  // frame index on the padded time axis (uniform over the workgroup)
    if ((p.tap_mode == 1 && tp >= p.prefix) || (p.tap_mode == 2 && tp < p.prefix)) continue;
    uint frame = uint(max(int(tp) - int(p.src_shift), 0));
    if (p.time_map == 1) frame = tp == 0 ? 0 : 1 + (tp - 1) / 2;
    else if (p.time_map == 2) frame = tp / 2;
    for (uint ci = 0; ci < p.cin; ++ci) {
      uint plane = ((b * p.cin + ci) * p.src_frames + frame) * hw;
      uint wk = ci * taps + kt * KH * KW;
      // Plain loop: drivers unroll it (on lavapipe that is ~1.5x faster than keeping the loop).
      for (uint kh = 0; kh < KH; ++kh) {
        int ih = int(oh * STRIDE) - p.pad_top + int(kh);
        bool row_ok = ih >= 0 && ih < int(UP * p.h);
        int row = int(plane) + clamp(ih, 0, int(UP * p.h) - 1) / int(UP) * int(p.w);
        float xv[SPAN];
        [[unroll]] for (uint j = 0; j < SPAN; ++j) {
          float v = texelFetch(src, row + col[j]).x;
          xv[j] = row_ok && col_ok[j] ? v : 0.0;
        }
        uint wstep = wk + kh * KW;
        float wv[NG];
        if (BCAST) {
          [[unroll]] for (uint g = 0; g < NG; ++g) wv[g] = load_w(woff[g] + wstep);
        }
        // Per channel: its KW weights, then each accumulator takes all KW taps in a row.
        [[unroll]] for (uint c = 0; c < CO_R; ++c) {
          float wc[KW];
          [[unroll]] for (uint kw = 0; kw < KW; ++kw) {
            uint n = c * KW + kw;
            wc[kw] = BCAST ? subgroupBroadcast(wv[n / 8], n % 8) : load_w(wrow[c] + wstep + kw);
          }
          [[unroll]] for (uint q = 0; q < PX_R; ++q) {
            float a = acc[c][q];
            [[unroll]] for (uint kw = 0; kw < KW; ++kw) a = fma(wc[kw], xv[q * STRIDE + kw], a);
            acc[c][q] = a;
          }
        }
      }
    }
  }

  if (!store) return;
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
