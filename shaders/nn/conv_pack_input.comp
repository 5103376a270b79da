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
#include "conv_pack_io.glsl"
// Invocation order (DeviceTuning::conv_pack_pixel_major): neighbouring invocations take neighbouring pixel segments
// of one vec4 of channels (a subgroup's reads of each channel plane contiguous); else neighbouring vec4s of one
// segment.
layout(constant_id = 1) const bool PIXEL_MAJOR = false;

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
  const uint prow = t % p.rows_p, q = p.q0 + t / p.rows_p;
  const PackRow r = pack_row(q, prow);
  // Per channel of the vec4: 0 another dispatch's channel (kept), 1 zero (past the chunk's channels), 2 read.
  uint mode[4];
  [[unroll]] for (uint j = 0; j < 4u; ++j) {
    uint ch = c4 * 4u + j;
    mode[j] = (ch < p.ca || (ch >= p.cb && p.cb != p.cc)) ? 0u : (ch >= p.cc ? 1u : 2u);
  }
  uint out_i = ((q * p.rows_p + prow) * p.cols_p + pc0) * p.cp4 + c4;
  for (uint pc = pc0; pc < pc1; ++pc, out_i += p.cp4) {
    vec4 v = p.partial != 0u ? load_out(out_i) : vec4(0.0);
    const bool inside = pack_inside(r, pc);
    [[unroll]] for (uint j = 0; j < 4u; ++j) {
      if (mode[j] == 1u || (mode[j] == 2u && !inside)) v[j] = 0.0;
      else if (mode[j] == 2u) v[j] = pack_value(r, c4 * 4u + j, pc);
    }
    store_out(out_i, v);
  }
}
