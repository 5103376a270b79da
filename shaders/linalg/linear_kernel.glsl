// Body of the linear shaders (linalg/linear.comp with subgroup operations, linalg/linear_nosubgroup.comp
// without: defines LINEAR_NO_SUBGROUPS for devices that lack subgroup shuffles).
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
#include "../common/erf.glsl"
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
layout(std430, binding = 2) writeonly buffer Yb { float y[]; };
layout(std430, binding = 3) readonly buffer Bias { uint bias[]; };     // f32, or 16-bit pairs
layout(std430, binding = 4) readonly buffer Scale { float scale[]; };
layout(std430, binding = 5) readonly buffer Shift { float shift[]; };
layout(std430, binding = 6) readonly buffer Gate { float gate[]; };
layout(std430, binding = 7) readonly buffer Res { float res[]; };

layout(push_constant) uniform Push {
  uint M, N, K, ldx, ldy, ldw;  // ldw: W row stride (the whole K; K is a chunk of it when K is split)
  uint x_off, w_off, y_off;      // element offsets in the bound views
  uint x_bs, w_bs, y_bs;         // batch strides in elements (w_bs 0: shared weight)
  uint bias_off, scale_off, shift_off, gate_off, res_off;
  uint vec_bs;                   // batch stride of scale, shift and gate (0: shared)
  uint flags;                    // bits 0-1 activation (1 GELU-tanh, 2 SiLU, 3 GELU-erf), 2 bias, 3 modulation, 4 gate,
                                 // 5 residual, 6-7 bias dtype (0 f32, 1 f16, 2 bf16)
} p;

float w_scalar(uint e) {
  uint u = texelFetch(Wt, int(e)).x;
  if (WTYPE == 0) return uintBitsToFloat(u);
  if (WTYPE == 1) return unpackHalf2x16(u).x;
  return uintBitsToFloat(u << 16);
}

// Eight consecutive weights starting at element e (a multiple of 8).
void w_step(uint e, out float w[8]) {
  if (WTYPE == 0) {
    uvec4 a = texelFetch(Wt, int(e >> 2)), b = texelFetch(Wt, int(e >> 2) + 1);
    w[0] = uintBitsToFloat(a.x); w[1] = uintBitsToFloat(a.y); w[2] = uintBitsToFloat(a.z); w[3] = uintBitsToFloat(a.w);
    w[4] = uintBitsToFloat(b.x); w[5] = uintBitsToFloat(b.y); w[6] = uintBitsToFloat(b.z); w[7] = uintBitsToFloat(b.w);
  } else {
    uvec4 t = texelFetch(Wt, int(e >> 3));
    if (WTYPE == 1) {
      vec2 a = unpackHalf2x16(t.x), b = unpackHalf2x16(t.y), c = unpackHalf2x16(t.z), d = unpackHalf2x16(t.w);
      w[0] = a.x; w[1] = a.y; w[2] = b.x; w[3] = b.y; w[4] = c.x; w[5] = c.y; w[6] = d.x; w[7] = d.y;
    } else {
      w[0] = uintBitsToFloat(t.x << 16); w[1] = uintBitsToFloat(t.x & 0xffff0000u);
      w[2] = uintBitsToFloat(t.y << 16); w[3] = uintBitsToFloat(t.y & 0xffff0000u);
      w[4] = uintBitsToFloat(t.z << 16); w[5] = uintBitsToFloat(t.z & 0xffff0000u);
      w[6] = uintBitsToFloat(t.w << 16); w[7] = uintBitsToFloat(t.w & 0xffff0000u);
    }
  }
}

void x_step(uint e, out float x[8]) {
  vec4 a = texelFetch(Xt, int(e >> 2)), b = texelFetch(Xt, int(e >> 2) + 1);
  x[0] = a.x; x[1] = a.y; x[2] = a.z; x[3] = a.w; x[4] = b.x; x[5] = b.y; x[6] = b.z; x[7] = b.w;
}

float load_bias(uint n) {
  uint dt = (p.flags >> 6) & 3u, i = p.bias_off + n;
  if (dt == 0u) return uintBitsToFloat(bias[i]);
  uint u = bias[i >> 1], half_bits = (i & 1u) == 0u ? (u & 0xffffu) : (u >> 16);
  return dt == 1u ? unpackHalf2x16(half_bits).x : uintBitsToFloat(half_bits << 16);
}

float activate(float f, uint act) {
  if (act == 1u) {  // GELU, tanh approximation; tanh(u) = 1 - 2/(e^{2u}+1) stays finite for large |u|
    float u = 0.7978845608028654 * (f + 0.044715 * f * f * f);
    return 0.5 * f * (2.0 - 2.0 / (exp(2.0 * u) + 1.0));
  }
  if (act == 2u) return f / (1.0 + exp(-f));
  if (act == 3u) return gelu_erf(f);
  return f;
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

  const uint flags = p.flags, act = flags & 3u;
  [[unroll]] for (int r = 0; r < ROWS; ++r) {
    uint m = m0 + r;
    if (m >= M) break;
    [[unroll]] for (int c = 0; c < COLS; ++c) {
      uint n = n0 + 8 * c + lane;
      if (n >= N) continue;
      float f = acc[r][c];
      if ((flags & 4u) != 0u) f += load_bias(n);
      f = activate(f, act);
      uint v = b * p.vec_bs + n;
      if ((flags & 8u) != 0u) f = f * (1.0 + scale[p.scale_off + v]) + shift[p.shift_off + v];
      if ((flags & 16u) != 0u) f *= gate[p.gate_off + v];
      uint o = b * p.y_bs + m * p.ldy + n;
      if ((flags & 32u) != 0u) f += res[p.res_off + o];
      y[p.y_off + o] = f;
    }
  }
}
