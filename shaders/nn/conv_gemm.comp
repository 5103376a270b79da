#version 450
#extension GL_GOOGLE_include_directive : require
// nn/conv_gemm: the convolution with subgroup shuffles. Its variant nn/conv_gemm_nosubgroup (CONV_NO_SUBGROUPS,
// shaders/variants.cmake) is for devices without subgroup shuffles: every lane fetches every pixel.
#extension GL_EXT_control_flow_attributes : require
#extension GL_EXT_samplerless_texture_functions : require
#ifndef CONV_NO_SUBGROUPS
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_shuffle : require
#endif
// Convolution as an implicit GEMM: Y[m, n] = bias[n] + sum_k X[m, k] W[n, k] with m an output pixel of the
// chunk (frame, row, column), n the output channel and k = (tap, input channel). The reduction runs tap by
// tap and, within a tap, over the input channels 8 at a time, so the operands are read as whole texels:
//  - X: the chunk's input repacked channels-last by conv_pack_input.comp, [frame][row][column][CP] f32
//    (CP = Cin rounded up to 8, zero-filled), read as RGBA32F: 8 channels of one pixel = 2 fetches.
//    Per tap, each lane computes where its pixel's input lies (padding, stride, nearest x2 upsampling):
//    outside the image it points at a zero pixel stored after the chunk, so the inner loop has no tests.
//  - W: repacked by conv_pack_weights.comp to [Cout][tap][CP] in the stored dtype, read as RGBA32UI:
//    8 bf16/f16 values per fetch (widened by w_step, common/weight_texels.glsl), or 4 f32.
//
// Register blocking (the linear kernel's scheme, tuned for CPU drivers where an 8-lane subgroup is one
// SIMD register and per-lane loads are the expensive part): a cluster of 8 lanes computes ROWS pixels x
// 8*COLS channels. Lane l owns channels n0 + l + 8c and, per 8-channel step, fetches its COLS weight
// texels and the X texels of ONE pixel (m0 + 8g + l); rotations of the cluster (subgroup shuffles, one
// register permute each on lavapipe, where a broadcast of one lane takes two) hand every pixel's values to
// every lane, lane l meeting pixel 8g + (l + i) mod 8 in rotation i: ROWS*COLS*8 FMAs per COLS + 2*ROWS/8
// fetches. DIRECT (small ROWS, or no subgroup shuffles): every lane fetches every pixel.
// On lavapipe every texel fetch is an out-of-line call that clobbers the vector registers (a quarter to a
// third of the time, with the accumulators' spills), and fma() is a multiply and an add.
// The tile shapes come from engine/src/tensor/kernel_tuning.cpp.
layout(local_size_x = 64) in;

layout(constant_id = 0) const int ROWS = 8;   // pixels per cluster tile (8 or 16 shuffled; 1..4 direct)
layout(constant_id = 1) const int COLS = 3;   // channel columns per lane
layout(constant_id = 2) const int WTYPE = 2;  // weight storage: 0 f32, 1 f16, 2 bf16
layout(constant_id = 3) const int LANES = 0;  // 0: subgroups of exactly 8; 1: clusters of 8 in wider subgroups; 2: no subgroup ops
layout(constant_id = 4) const int SG_M = 2;   // clusters of a workgroup along M (8 / SG_M along N)
// 8-channel steps per trip of the channel loop (CP must be a multiple of 8 * KU): lavapipe merges every
// loop-carried value (the accumulators) with the execution mask once per trip, so longer trips amortise it.
layout(constant_id = 5) const int KU = 1;
layout(constant_id = 6) const int BTYPE = 2;  // bias storage (conv_bias.glsl): 0 f32, 1 f16, 2 bf16

#ifdef CONV_NO_SUBGROUPS
const bool DIRECT = true;
#else
const bool DIRECT = ROWS < 8 || LANES == 2;
#endif
const int RG = DIRECT ? ROWS : ROWS / 8;  // pixels a lane fetches per step
const int SG_N = 8 / SG_M;

layout(binding = 0) uniform textureBuffer Xt;   // RGBA32F, packed input chunk + one zero pixel
layout(binding = 1) uniform utextureBuffer Wt;  // RGBA32UI, packed weights
layout(std430, binding = 2) readonly buffer Bias { uint bias[]; };  // BTYPE (16-bit pairs)
layout(std430, binding = 3) buffer Y { float y[]; };  // read back only when accumulating

layout(push_constant) uniform Push {
  uint M, N;                  // output pixels of the chunk, output channels
  uint cp;                    // packed channels (multiple of 8)
  uint kt, kh, kw;            // kernel extent
  uint stride, up;            // conv stride; 2: the input is read nearest-x2 upsampled (in H and W)
  uint wo, rows;              // output columns and rows in the chunk
  uint oh0;                   // first output row of the chunk
  int pad_top, pad_left;
  uint in_h, in_w;            // input size as the conv sees it (upsampled when up = 2)
  uint src_r0, src_rows, src_w;  // packed rows [src_r0, src_r0 + src_rows) of the source, src_w columns
  uint zero_texel;            // texel index of the zero pixel
  uint y_base;                // y element of (chunk's first frame, row 0, column 0, channel 0)
  uint ys_f, ys_h, ys_w, ys_c;
  uint has_bias;
  uint n_base;      // first output channel of this dispatch (the bias index; y_base already points at it)
  uint accumulate;  // 1: y += the sum (a later chunk of input channels); the bias came with the first
  uint ow0;         // first output column of the chunk (wo: its column count; y_base points at it)
  uint src_c0;      // first source column packed (src_w: packed columns)
} p;

#include "conv_bias.glsl"

#include "weight_texels.glsl"  // w_step: eight weights from Wt

// The value of the cluster lane r places further on (a rotation of the cluster by r): lane l gets lane
// (l + r) mod 8's value. CPU drivers turn this into one register permute, where a broadcast of one lane
// (the same for every lane) takes two.
float rotate(float v, int r) {
#ifdef CONV_NO_SUBGROUPS
  return v;  // unused: this variant always fetches every pixel directly
#else
  return subgroupShuffle(v, (gl_SubgroupInvocationID & ~7u) | ((gl_SubgroupInvocationID + uint(r)) & 7u));
#endif
}

void main() {
  uint lane = gl_LocalInvocationIndex & 7u, cluster = gl_LocalInvocationIndex >> 3;
#ifndef CONV_NO_SUBGROUPS
  if (LANES != 2) {
    lane = gl_SubgroupInvocationID & 7u;
    cluster = gl_SubgroupID * (gl_SubgroupSize >> 3) + (gl_SubgroupInvocationID >> 3);
  }
#endif
  const uint m0 = (gl_WorkGroupID.x * SG_M + cluster / SG_N) * ROWS;
  const uint n0 = (gl_WorkGroupID.y * SG_N + cluster % SG_N) * (8 * COLS);
  const uint M = p.M, N = p.N, cp = p.cp;

  // The pixels this lane fetches, as (frame in chunk, output row, output column); tails are clamped into
  // the chunk (duplicates, never stored).
  uint pf[RG];
  int ph[RG], pw[RG];
  [[unroll]] for (int g = 0; g < RG; ++g) {
    uint m = min(DIRECT ? m0 + g : m0 + 8 * g + lane, M - 1u);
    uint ow = m % p.wo, t = m / p.wo;
    pf[g] = t / p.rows;
    ph[g] = int((p.oh0 + t % p.rows) * p.stride) - p.pad_top;
    pw[g] = int((p.ow0 + ow) * p.stride) - p.pad_left;
  }
  uint we[COLS];
  const uint wrow = p.kt * p.kh * p.kw * cp;
  [[unroll]] for (int c = 0; c < COLS; ++c) we[c] = min(n0 + 8 * c + lane, N - 1u) * wrow;

  float acc[ROWS][COLS];
  [[unroll]] for (int r = 0; r < ROWS; ++r)
    [[unroll]] for (int c = 0; c < COLS; ++c) acc[r][c] = 0.0;

  const uint cp4 = cp >> 2, up = p.up;
  uint wk = 0;  // packed weight element of (tap, channel 0)
  for (uint a = 0; a < p.kt; ++a)
    for (uint u = 0; u < p.kh; ++u)
      for (uint v = 0; v < p.kw; ++v, wk += cp) {
        uint xt[RG];
        [[unroll]] for (int g = 0; g < RG; ++g) {
          int ih = ph[g] + int(u), iw = pw[g] + int(v);
          bool inside = ih >= 0 && ih < int(p.in_h) && iw >= 0 && iw < int(p.in_w);
          uint pix = ((pf[g] + a) * p.src_rows + uint(ih) / up - p.src_r0) * p.src_w + uint(iw) / up - p.src_c0;
          xt[g] = inside ? pix * cp4 : p.zero_texel;
        }
        for (uint k0 = 0; k0 < cp; k0 += 8 * KU)
          [[unroll]] for (int ku = 0; ku < KU; ++ku) {
            uint k = k0 + 8 * ku;
            float xv[RG][8], wv[COLS][8];
            [[unroll]] for (int g = 0; g < RG; ++g) {
              vec4 lo = texelFetch(Xt, int(xt[g] + (k >> 2))), hi = texelFetch(Xt, int(xt[g] + (k >> 2) + 1));
              xv[g][0] = lo.x; xv[g][1] = lo.y; xv[g][2] = lo.z; xv[g][3] = lo.w;
              xv[g][4] = hi.x; xv[g][5] = hi.y; xv[g][6] = hi.z; xv[g][7] = hi.w;
            }
            [[unroll]] for (int c = 0; c < COLS; ++c) w_step(we[c] + wk + k, wv[c]);
            if (DIRECT) {
              [[unroll]] for (int j = 0; j < 8; ++j)
                [[unroll]] for (int r = 0; r < ROWS; ++r)
                  [[unroll]] for (int c = 0; c < COLS; ++c) acc[r][c] = fma(xv[r][j], wv[c][j], acc[r][c]);
            } else {
              [[unroll]] for (int j = 0; j < 8; ++j)
                [[unroll]] for (int g = 0; g < RG; ++g)
                  [[unroll]] for (int i = 0; i < 8; ++i) {
                    float xb = i == 0 ? xv[g][j] : rotate(xv[g][j], i);
                    [[unroll]] for (int c = 0; c < COLS; ++c) acc[8 * g + i][c] = fma(xb, wv[c][j], acc[8 * g + i][c]);
                  }
            }
          }
      }

  // Shuffled tiles hold pixel 8g + (lane + i) mod 8 of the tile in acc[8g + i] (the rotations above).
  [[unroll]] for (int r = 0; r < ROWS; ++r) {
    uint m = m0 + (DIRECT ? uint(r) : uint(r & ~7) + ((lane + uint(r)) & 7u));
    if (m >= M) continue;
    uint ow = m % p.wo, t = m / p.wo;
    uint ybase = p.y_base + (t / p.rows) * p.ys_f + (t % p.rows) * p.ys_h + ow * p.ys_w;
    [[unroll]] for (int c = 0; c < COLS; ++c) {
      uint n = n0 + 8 * c + lane;
      if (n >= N) continue;
      float f = acc[r][c];
      if (p.accumulate != 0u) f = y[ybase + n * p.ys_c] + f;
      else if (p.has_bias != 0u) f += w_bias(p.n_base + n);
      y[ybase + n * p.ys_c] = f;
    }
  }
}
