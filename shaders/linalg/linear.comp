#version 450
#extension GL_GOOGLE_include_directive : require
// linalg/linear: the linear layer with subgroup shuffles (every Vulkan 1.1+ GPU and lavapipe). Its variant
// linalg/linear_nosubgroup (LINEAR_NO_SUBGROUPS, shaders/variants.cmake) is for devices without subgroup
// shuffles: every lane fetches its rows itself.
#extension GL_EXT_control_flow_attributes : require
#extension GL_EXT_samplerless_texture_functions : require  // textureBuffer + texelFetch: no combined sampler (SPIR-V 1.6)
#ifndef LINEAR_NO_SUBGROUPS
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_shuffle : require
#endif
// Linear layer: Y[b] = epilogue(X[b] · W[b]ᵀ), X f32 [M,K] (row stride ldx), W [N,K] stored f32, f16 or bf16,
// Y f32 [M,N] (row stride ldy), fp32 accumulation. Epilogue, in order: + bias[n]; GELU (tanh or erf) or SiLU;
// modulation f·(1 + scale[n]) + shift[n]; then residual: y = r + gate[n]·f, or r + f without a gate
// (gate without residual: y = gate[n]·f). The residual may alias Y: each element is read before it is
// written, by the same invocation.
//
// Layout of the work (tuned for lavapipe, where each 8-lane subgroup is one SIMD register and every
// per-lane load is expensive, texel fetches being ~3x cheaper than storage-buffer loads): the workgroup
// is 8 clusters of 8 lanes; a cluster computes a ROWS x (8*COLS) tile of Y. Lane l owns the columns
// n0 + l + 8c and, for every K step, fetches its columns' weights and ONE row of X (row m0 + 8g + l), then
// the X values of all ROWS rows reach every lane by subgroup shuffles: ROWS*COLS FMAs per k for
// COLS + ROWS/8 fetches (and ROWS shuffles). A K step is 8 values (texels RGBA32F for X, RGBA32UI for W:
// two texels of f32 or one of eight packed 16-bit values, so no 16-bit storage is needed), or 1 value in
// the scalar variant used when K or offsets are not multiples of 8. No shared memory, no barriers.
layout(local_size_x = 64) in;

layout(constant_id = 0) const int ROWS = 8;   // rows per cluster tile: 8 or 16 shuffled from lanes; < 8: fetched by every lane
layout(constant_id = 1) const int COLS = 3;   // columns per lane
layout(constant_id = 2) const int WTYPE = 0;  // weight storage: 0 f32, 1 f16, 2 bf16
layout(constant_id = 3) const int KVEC = 1;   // 1: 8-value K steps (RGBA texels); 0: scalar texels
layout(constant_id = 4) const int LANES = 0;  // 0: subgroups of exactly 8; 1: clusters of 8 in wider subgroups; 2: no subgroup ops
layout(constant_id = 5) const int SG_M = 2;   // clusters of a workgroup along M (8 / SG_M along N)

const int KS = 1 + 7 * KVEC;                        // K values per step
#ifdef LINEAR_NO_SUBGROUPS
const bool DIRECT = true;
#else
const bool DIRECT = ROWS < 8 || LANES == 2;         // every lane fetches every row itself
#endif
const int RG = DIRECT ? ROWS : ROWS / 8;            // X rows a lane fetches per step
const int SG_N = 8 / SG_M;

layout(binding = 0) uniform textureBuffer Xt;   // f32: RGBA32F (KVEC) or R32F
layout(binding = 1) uniform utextureBuffer Wt;  // RGBA32UI (KVEC), or R32UI (f32) / R16UI (16-bit)
#include "linear_epilogue.glsl"

float w_scalar(uint e) {
  uint u = texelFetch(Wt, int(e)).x;
  if (WTYPE == 0) return uintBitsToFloat(u);
  if (WTYPE == 1) return unpackHalf2x16(u).x;
  return uintBitsToFloat(u << 16);
}

#include "weight_texels.glsl"  // w_step: eight weights from Wt

void x_step(uint e, out float x[8]) {
  vec4 a = texelFetch(Xt, int(e >> 2)), b = texelFetch(Xt, int(e >> 2) + 1);
  x[0] = a.x; x[1] = a.y; x[2] = a.z; x[3] = a.w; x[4] = b.x; x[5] = b.y; x[6] = b.z; x[7] = b.w;
}


// X value of row r of the lane's 8-row group, from lane r of the cluster. On lavapipe a shuffle with a
// constant index compiles to one register permute; subgroupBroadcast compiles to a loop over the lanes
// (it looks for the active lanes): the whole GEMM ran ~1.6x slower with it.
float bcast(float v, int r) {
#ifdef LINEAR_NO_SUBGROUPS
  return v;  // unused: this variant always fetches every row directly
#else
  if (LANES == 0) return subgroupShuffle(v, uint(r));
  return subgroupShuffle(v, (gl_SubgroupInvocationID & ~7u) + uint(r));
#endif
}

void main() {
  uint lane, cluster;
#ifdef LINEAR_NO_SUBGROUPS
  lane = gl_LocalInvocationIndex & 7u;
  cluster = gl_LocalInvocationIndex >> 3;
#else
  if (LANES == 2) {
    lane = gl_LocalInvocationIndex & 7u;
    cluster = gl_LocalInvocationIndex >> 3;
  } else {
    lane = gl_SubgroupInvocationID & 7u;
    cluster = gl_SubgroupID * (gl_SubgroupSize >> 3) + (gl_SubgroupInvocationID >> 3);
  }
#endif
  const uint b = gl_WorkGroupID.z;
  const uint m0 = (gl_WorkGroupID.y * SG_M + cluster / SG_N) * ROWS;
  const uint n0 = (gl_WorkGroupID.x * SG_N + cluster % SG_N) * (8 * COLS);
  const uint M = p.M, N = p.N, K = p.K;

  // Base element of each row this lane fetches (clamped into the matrix: tails compute duplicates that
  // are never stored, and no fetch leaves the tensor).
  uint xe[RG], we[COLS];
  [[unroll]] for (int g = 0; g < RG; ++g) {
    uint m = DIRECT ? m0 + g : m0 + 8 * g + lane;
    xe[g] = p.x_off + b * p.x_bs + min(m, M - 1u) * p.ldx;
  }
  [[unroll]] for (int c = 0; c < COLS; ++c) we[c] = p.w_off + b * p.w_bs + min(n0 + 8 * c + lane, N - 1u) * p.ldw;

  float acc[ROWS][COLS];
  [[unroll]] for (int r = 0; r < ROWS; ++r)
    [[unroll]] for (int c = 0; c < COLS; ++c) acc[r][c] = 0.0;

  for (uint k = 0; k < K; k += KS) {
    float xv[RG][KS], wv[COLS][KS];
    [[unroll]] for (int g = 0; g < RG; ++g) {
      if (KVEC == 1) {
        float t[8];
        x_step(xe[g] + k, t);
        [[unroll]] for (int j = 0; j < KS; ++j) xv[g][j] = t[j];
      } else {
        xv[g][0] = texelFetch(Xt, int(xe[g] + k)).x;
      }
    }
    [[unroll]] for (int c = 0; c < COLS; ++c) {
      if (KVEC == 1) {
        float t[8];
        w_step(we[c] + k, t);
        [[unroll]] for (int j = 0; j < KS; ++j) wv[c][j] = t[j];
      } else {
        wv[c][0] = w_scalar(we[c] + k);
      }
    }
    [[unroll]] for (int j = 0; j < KS; ++j) {
      if (DIRECT) {
        [[unroll]] for (int r = 0; r < ROWS; ++r)
          [[unroll]] for (int c = 0; c < COLS; ++c) acc[r][c] = fma(xv[r][j], wv[c][j], acc[r][c]);
      } else {
        [[unroll]] for (int g = 0; g < RG; ++g)
          [[unroll]] for (int i = 0; i < 8; ++i) {
            float xb = bcast(xv[g][j], i);
            [[unroll]] for (int c = 0; c < COLS; ++c) acc[8 * g + i][c] = fma(xb, wv[c][j], acc[8 * g + i][c]);
          }
      }
    }
  }

  [[unroll]] for (int r = 0; r < ROWS; ++r) {
    uint m = m0 + r;
    if (m >= M) break;
    [[unroll]] for (int c = 0; c < COLS; ++c) {
      uint n = n0 + 8 * c + lane;
      if (n < N) store_output(b, m, n, acc[r][c]);
    }
  }
}
