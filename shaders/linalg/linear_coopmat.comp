#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_cooperative_matrix : require
// Linear layer Y = epilogue(X·Wᵀ), the "coopmat" family (tensor cores through VK_KHR_cooperative_matrix).
// Its fp32 twin, tested on lavapipe, is linear_tiled.comp: same element loads (zero-filled outside M/N/K),
// same epilogue (linear_storage_io.glsl); only the tile product differs.
//
// The layout comes from the tuning table (DeviceTuning::linear_coopmat, coopmat, coopmat_lanes; checked
// against the device by tensor/coopmat_layout.cpp, which also requires the subgroup size at pipeline
// creation): SG_M x SG_N subgroups, each owning FM x FN fp32 accumulator fragments of FRAG_M x FRAG_N, so a
// workgroup computes a BM x BN tile of Y. On the H200: 8 subgroups of 32 as 2 x 4, 4 x 2 fragments of
// 16 x 16 x 16 each (64 x 32 outputs), BM = BN = 128; on lavapipe (8 lanes, 32 KiB) the same arrangement of
// 8 x 8 x 8 fragments, BM = BN = 64. Per K step of BK values, X[BM x BK] (f32 -> fp16) and W[BN x BK]
// (f32/f16/bf16 -> fp16) are staged in shared memory, double-buffered: the next step's global loads are
// issued into registers before this step's MMAs and stored to the other buffer after them, so one barrier per
// step suffices. fp16 operands: |x| > 65504 becomes inf (callers that may exceed this set
// LinearEpilogue::fp16_operands_ok = false and get the tiled kernel); products accumulate in fp32.
// Epilogue: each subgroup stores one accumulator fragment at a time to its own FRAG_M x FRAG_N f32 staging
// block and its lanes apply the epilogue to those outputs with bounds checks.
// Shared memory: 2 x (BM + BN) x (BK + 8) halves + one fragment per subgroup (48 KiB on the H200).
#include "linear_storage_io.glsl"

layout(local_size_x_id = 9) in;                 // WG = SG_M * SG_N * the subgroup size
layout(constant_id = 0) const uint SG_M = 2;    // subgroups along M
layout(constant_id = 1) const uint SG_N = 4;    // subgroups along N
layout(constant_id = 3) const uint BK = 32;     // K per step: a multiple of 8 and of FRAG_K; WG a multiple of it
layout(constant_id = 4) const uint FRAG_K = 16; // the device's fragment shape, FRAG_M x FRAG_N x FRAG_K
layout(constant_id = 5) const uint FM = 4;      // fragments per subgroup along M
layout(constant_id = 6) const uint FN = 2;      // fragments per subgroup along N
layout(constant_id = 7) const uint FRAG_M = 16;
layout(constant_id = 8) const uint FRAG_N = 16;

const uint WG = gl_WorkGroupSize.x;
const uint BM = SG_M * FM * FRAG_M, BN = SG_N * FN * FRAG_N;
const uint LDS = BK + 8;        // shared row stride in halves: a multiple of 8 (16 bytes) for coopMatLoad
const uint ROWS = WG / BK;      // rows the workgroup stages per pass (invocation t: column t % BK, row t / BK)
const uint PER_X = BM / ROWS, PER_W = BN / ROWS;  // passes per operand and step (16 each on the H200)
const uint FRAG = FRAG_M * FRAG_N;

shared float16_t sx[2 * BM * LDS];
shared float16_t sw[2 * BN * LDS];
shared float stage[SG_M * SG_N * FRAG];

void main() {
  const uint t = gl_LocalInvocationIndex;
  const uint b = gl_WorkGroupID.z, m0 = gl_WorkGroupID.y * BM, n0 = gl_WorkGroupID.x * BN;
  const uint sg = gl_SubgroupID, lane = gl_SubgroupInvocationID;
  const uint sm = sg / SG_N, sn = sg % SG_N;
  // Staging map: invocation t loads k = t % BK of rows t / BK + ROWS·j (BK consecutive floats per row: coalesced).
  const uint lk = t % BK, lr = t / BK;

  coopmat<float, gl_ScopeSubgroup, FRAG_M, FRAG_N, gl_MatrixUseAccumulator> acc[FM * FN];
  [[unroll]] for (uint f = 0; f < FM * FN; ++f)
    acc[f] = coopmat<float, gl_ScopeSubgroup, FRAG_M, FRAG_N, gl_MatrixUseAccumulator>(0.0);

  float rx[PER_X], rw[PER_W];
  const uint steps = (p.K + BK - 1) / BK;
  if (steps > 0) {
    [[unroll]] for (uint j = 0; j < PER_X; ++j) sx[(lr + ROWS * j) * LDS + lk] = float16_t(load_x(b, m0 + lr + ROWS * j, lk));
    [[unroll]] for (uint j = 0; j < PER_W; ++j) sw[(lr + ROWS * j) * LDS + lk] = float16_t(load_w(b, n0 + lr + ROWS * j, lk));
  }
  barrier();

  for (uint s = 0; s < steps; ++s) {
    const uint cur = s & 1u, nxt = cur ^ 1u;
    const bool more = s + 1 < steps;
    if (more) {
      const uint k = (s + 1) * BK + lk;
      [[unroll]] for (uint j = 0; j < PER_X; ++j) rx[j] = load_x(b, m0 + lr + ROWS * j, k);
      [[unroll]] for (uint j = 0; j < PER_W; ++j) rw[j] = load_w(b, n0 + lr + ROWS * j, k);
    }
    const uint xb = cur * BM * LDS + sm * (FM * FRAG_M) * LDS, wb = cur * BN * LDS + sn * (FN * FRAG_N) * LDS;
    [[unroll]] for (uint kk = 0; kk < BK; kk += FRAG_K) {
      coopmat<float16_t, gl_ScopeSubgroup, FRAG_M, FRAG_K, gl_MatrixUseA> a[FM];
      coopmat<float16_t, gl_ScopeSubgroup, FRAG_K, FRAG_N, gl_MatrixUseB> w[FN];
      [[unroll]] for (uint i = 0; i < FM; ++i)
        coopMatLoad(a[i], sx, xb + i * FRAG_M * LDS + kk, LDS, gl_CooperativeMatrixLayoutRowMajor);
      // B[k][n] = W[n][k]: W's rows in shared memory are B's columns.
      [[unroll]] for (uint j = 0; j < FN; ++j)
        coopMatLoad(w[j], sw, wb + j * FRAG_N * LDS + kk, LDS, gl_CooperativeMatrixLayoutColumnMajor);
      [[unroll]] for (uint i = 0; i < FM; ++i)
        [[unroll]] for (uint j = 0; j < FN; ++j) acc[i * FN + j] = coopMatMulAdd(a[i], w[j], acc[i * FN + j]);
    }
    if (more) {
      [[unroll]] for (uint j = 0; j < PER_X; ++j) sx[nxt * BM * LDS + (lr + ROWS * j) * LDS + lk] = float16_t(rx[j]);
      [[unroll]] for (uint j = 0; j < PER_W; ++j) sw[nxt * BN * LDS + (lr + ROWS * j) * LDS + lk] = float16_t(rw[j]);
    }
    barrier();
  }

  const uint st = sg * FRAG;
  [[unroll]] for (uint i = 0; i < FM; ++i)
    [[unroll]] for (uint j = 0; j < FN; ++j) {
      coopMatStore(acc[i * FN + j], stage, st, FRAG_N, gl_CooperativeMatrixLayoutRowMajor);
      subgroupMemoryBarrierShared();
      subgroupBarrier();
      const uint mb = m0 + sm * (FM * FRAG_M) + i * FRAG_M, nb = n0 + sn * (FN * FRAG_N) + j * FRAG_N;
      for (uint e = lane; e < FRAG; e += gl_SubgroupSize) {
        const uint m = mb + e / FRAG_N, n = nb + e % FRAG_N;
        if (m < p.M && n < p.N) store_output(b, m, n, stage[st + e]);
      }
      subgroupMemoryBarrierShared();
      subgroupBarrier();  // every lane read the block before the next fragment overwrites it
    }
}
