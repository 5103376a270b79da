#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_samplerless_texture_functions : require
#extension GL_EXT_control_flow_attributes : require
// The input of one convolution chunk, repacked channels-last for conv_gemm: out[frame][row][col][CP]
// (CP = channels rounded up to 8, the extra channels zero) over `frames` frames of the time-padded axis
// starting at tp0 and source rows [r0, r0 + rows), followed by one zero pixel (the target of every tap
// that falls into the spatial padding). One invocation writes one vec4 (4 channels) of `seg` consecutive
// pixels of one row (kernel_tuning.cpp: the whole row on CPU drivers, where the index arithmetic's integer
// divisions are a scalar loop per lane, a few pixels on GPUs).
// With a halo (the shifted-GEMM convolution, ops_conv_shifted.cpp) the rows and columns are those of the zero-padded
// grid: rows_p rows of which rows [halo_top, halo_top + rows) are source rows [r0, r0 + rows), cols_p columns of
// which [halo_left, halo_left + wc) are source columns [col0, col0 + wc), every other pixel zero; without one,
// rows_p = rows, cols_p = wc and both halos 0. up_shift 1: the rows and columns (r0, rows, col0, wc and the grid) are
// those of x's nearest x2 spatial upsampling, row r and column c reading x's (r / 2, c / 2) (the shifted GEMM's fused
// upsampling convolution); 0: x's own.
// Only source columns [col0, col0 + wc) are packed (a row split into column chunks). The channels are those of one input-channel chunk [c0, c0 + cc) of x. Within the device's limits one
// dispatch packs a sub-range (packed frames [q0, q0 + nq), channels [ca, cb) of the chunk) read through
// sub-views of X and Cache starting at elements x_base / cache_base; `partial` dispatches (a channel range
// that does not own whole vec4s) merge their channels into the vec4 already written.
//
// Frame tp of the padded axis is, by time_mode:
//   0: x frame max(tp - prefix, 0)  (causal conv without cache: the prefix replicates frame 0; plain conv2d: prefix 0)
//   1: x frame tp == 0 ? 0 : 1 + (tp - 1) / 2   (CogVideoXUpsample3D, odd frame count)
//   2: x frame tp / 2                           (CogVideoXUpsample3D, even frame count)
//   3: tp < prefix ? cache frame tp : x frame tp - prefix   (causal conv with the previous batch's cache)
//
// OUT_F16 (the tensor-core kernel's operand type, DeviceTuning::conv_activations_fp16): the packed chunk holds fp16,
// 4 channels per 8 bytes (the values rounded to nearest even, as that kernel rounds an fp32 chunk), at the same
// indices in units of 4 channels: half the bytes written here and read by every tap of the GEMM.
layout(local_size_x = 64) in;
#include "index.glsl"
layout(constant_id = 0) const bool OUT_F16 = false;
// Invocation order (DeviceTuning::conv_pack_pixel_major): neighbouring invocations take neighbouring pixel segments
// of one vec4 of channels (a subgroup's reads of each channel plane contiguous); else neighbouring vec4s of one
// segment.
layout(constant_id = 1) const bool PIXEL_MAJOR = false;

layout(binding = 0) uniform textureBuffer X;      // R32F, [B, C, F, H, W]
layout(binding = 1) uniform textureBuffer Cache;  // R32F, [B, C, prefix, H, W] (time_mode 3; else any)
layout(std430, binding = 2) buffer Out { vec4 o[]; };
layout(std430, binding = 2) buffer OutH { uvec2 oh[]; };  // OUT_F16

vec4 load_out(uint i) { return OUT_F16 ? vec4(unpackHalf2x16(oh[i].x), unpackHalf2x16(oh[i].y)) : o[i]; }
void store_out(uint i, vec4 v) {
  if (OUT_F16) {
    oh[i] = uvec2(packHalf2x16(v.xy), packHalf2x16(v.zw));
  } else {
    o[i] = v;
  }
}

layout(push_constant) uniform Push {
  uint cp4;           // CP / 4
  uint c, src_frames, h, w;
  uint batch;         // batch item packed
  uint tp0, frames, r0, rows;
  uint prefix, time_mode;
  uint c0, cc;         // the chunk's first input channel, its channel count
  uint q0, nq;         // packed frames of this dispatch
  uint ca, cb;         // chunk channels of this dispatch (cb == cc: also the zero channels up to cp)
  uint c4a, nc4;       // vec4 columns of this dispatch
  uint x_base, cache_base;  // element of x / cache at the start of the bound views
  uint zero, partial;  // 1: also write the zero pixel; 1: merge into the existing vec4s
  uint col0, wc;       // source columns [col0, col0 + wc) (w: x's width)
  uint seg;           // packed pixels of a row per invocation
  uint halo_top, rows_p, halo_left, cols_p;  // the packed grid (see above)
  uint up_shift;      // 1: rows and columns of the x2 upsampling (see above)
} p;

void main() {
  uint i = flat_index();
  const uint nseg = (p.cols_p + p.seg - 1u) / p.seg;  // segments per packed row
  uint items = p.nq * p.rows_p * nseg * p.nc4;
  if (i >= items) {  // the zero pixel, after frames * rows_p * cols_p pixels
    if (p.zero != 0u && i < items + p.cp4) store_out(p.frames * p.rows_p * p.cols_p * p.cp4 + i - items, vec4(0.0));
    return;
  }
  const uint segs = p.nq * p.rows_p * nseg;
  uint c4 = p.c4a + (PIXEL_MAJOR ? i / segs : i % p.nc4), s = PIXEL_MAJOR ? i % segs : i / p.nc4, t = s / nseg;
  uint pc0 = (s % nseg) * p.seg, pc1 = min(pc0 + p.seg, p.cols_p);
  const uint prow = t % p.rows_p;  // the packed row; source row r0 + prow - halo_top where that is one
  const bool row_in = prow >= p.halo_top && prow - p.halo_top < p.rows;
  uint row = p.r0 + prow - p.halo_top, q = p.q0 + t / p.rows_p, tp = p.tp0 + q;
  bool from_cache = p.time_mode == 3u && tp < p.prefix;
  uint frame;
  if (p.time_mode == 1u) frame = tp == 0u ? 0u : 1u + (tp - 1u) / 2u;
  else if (p.time_mode == 2u) frame = tp / 2u;
  else if (p.time_mode == 3u) frame = from_cache ? tp : tp - p.prefix;
  else frame = uint(max(int(tp) - int(p.prefix), 0));
  uint frames = from_cache ? p.prefix : p.src_frames;
  uint hw = p.h * p.w, inner = (row >> p.up_shift) * p.w;
  // Per channel of the vec4: 0 another dispatch's channel (kept), 1 zero (past the chunk's channels), 2 read.
  uint mode[4], e[4];
  [[unroll]] for (uint j = 0; j < 4u; ++j) {
    uint ch = c4 * 4u + j;
    mode[j] = (ch < p.ca || (ch >= p.cb && p.cb != p.cc)) ? 0u : (ch >= p.cc ? 1u : 2u);
    e[j] = ((p.batch * p.c + p.c0 + min(ch, p.cc - 1u)) * frames + frame) * hw + inner;
    e[j] -= from_cache ? p.cache_base : p.x_base;
  }
  uint out_i = ((q * p.rows_p + prow) * p.cols_p + pc0) * p.cp4 + c4;
  for (uint pc = pc0; pc < pc1; ++pc, out_i += p.cp4) {
    vec4 v = p.partial != 0u ? load_out(out_i) : vec4(0.0);
    const uint col = pc - p.halo_left;  // source column col0 + col where inside
    const bool inside = row_in && pc >= p.halo_left && col < p.wc;
    [[unroll]] for (uint j = 0; j < 4u; ++j) {
      if (mode[j] == 1u || (mode[j] == 2u && !inside)) v[j] = 0.0;
      else if (mode[j] == 2u) {
        const int at = int(e[j] + ((p.col0 + col) >> p.up_shift));
        v[j] = from_cache ? texelFetch(Cache, at).x : texelFetch(X, at).x;
      }
    }
    store_out(out_i, v);
  }
}
