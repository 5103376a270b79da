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
// A workgroup computes a 128 x 128 tile of Y with 8 subgroups of 32 (designed for subgroup size 32; the host
// tuning only selects this kernel on such devices), arranged 2 (M) x 4 (N): each subgroup owns 64 x 32
// outputs = 4 x 2 fp32 accumulator fragments of 16 x 16. Per K step of 32 values, X[128 x 32] (f32 -> fp16)
// and W[128 x 32] (f32/f16/bf16 -> fp16) are staged in shared memory, double-buffered: the next step's
// global loads are issued into registers before this step's MMAs and stored to the other buffer after
// them, so one barrier per step suffices. fp16 operands: |x| > 65504 becomes inf (callers that may exceed
// this set LinearEpilogue::fp16_operands_ok = false and get the tiled kernel); products accumulate in fp32.
// Epilogue: each subgroup stores one accumulator fragment at a time to its own 16 x 16 f32 staging block
// and its lanes apply the epilogue to those 256 outputs with bounds checks.
// Shared memory: 2 x (128 + 128) x 40 halves (40 KiB) + 8 x 1 KiB staging = 48 KiB.
#include "linear_storage_io.glsl"

layout(local_size_x = 256) in;
layout(constant_id = 0) const uint BM_SPEC = 128;  // must be 128 (host-checked; kept for a uniform spec layout)
layout(constant_id = 1) const uint BN_SPEC = 128;  // must be 128
layout(constant_id = 3) const uint BK_SPEC = 32;   // must be 32
layout(constant_id = 4) const uint CK = 16;        // the device's coopmat K: 16 or 8

const uint BM = 128, BN = 128, BK = 32;
const uint SGN = 4;          // subgroups along N (2 along M)
const uint FM = 4, FN = 2;   // fragments per subgroup along M, N
const uint LDS = BK + 8;     // shared row stride in halves: a multiple of 8 (16 bytes) for coopMatLoad
const uint PER = BM * BK / 256;  // elements each invocation stages per operand and step (16)

shared float16_t sx[2 * BM * LDS];
shared float16_t sw[2 * BN * LDS];
shared float stage[8 * 256];

void main() {
  const uint t = gl_LocalInvocationIndex;
  const uint b = gl_WorkGroupID.z, m0 = gl_WorkGroupID.y * BM, n0 = gl_WorkGroupID.x * BN;
  const uint sg = gl_SubgroupID, lane = gl_SubgroupInvocationID;
  const uint sm = sg / SGN, sn = sg % SGN;
  // Staging map: invocation t loads k = t % 32 of rows t / 32 + 8j (32 consecutive floats per row: coalesced).
  const uint lk = t % BK, lr = t / BK;

  coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator> acc[FM * FN];
  [[unroll]] for (uint f = 0; f < FM * FN; ++f) acc[f] = coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator>(0.0);

  float rx[PER], rw[PER];
  const uint steps = (p.K + BK - 1) / BK;
  if (steps > 0) {
    [[unroll]] for (uint j = 0; j < PER; ++j) {
      rx[j] = load_x(b, m0 + lr + 8 * j, lk);
      rw[j] = load_w(b, n0 + lr + 8 * j, lk);
    }
    [[unroll]] for (uint j = 0; j < PER; ++j) {
      sx[(lr + 8 * j) * LDS + lk] = float16_t(rx[j]);
      sw[(lr + 8 * j) * LDS + lk] = float16_t(rw[j]);
    }
  }
  barrier();

  for (uint s = 0; s < steps; ++s) {
    const uint cur = s & 1u, nxt = cur ^ 1u;
    const bool more = s + 1 < steps;
    if (more) {
      const uint k = (s + 1) * BK + lk;
      [[unroll]] for (uint j = 0; j < PER; ++j) {
        rx[j] = load_x(b, m0 + lr + 8 * j, k);
        rw[j] = load_w(b, n0 + lr + 8 * j, k);
      }
    }
    const uint xb = cur * BM * LDS + sm * 64 * LDS, wb = cur * BN * LDS + sn * 32 * LDS;
    [[unroll]] for (uint kk = 0; kk < BK; kk += CK) {
      coopmat<float16_t, gl_ScopeSubgroup, 16, CK, gl_MatrixUseA> a[FM];
      coopmat<float16_t, gl_ScopeSubgroup, CK, 16, gl_MatrixUseB> w[FN];
      [[unroll]] for (uint i = 0; i < FM; ++i)
        coopMatLoad(a[i], sx, xb + i * 16 * LDS + kk, LDS, gl_CooperativeMatrixLayoutRowMajor);
      // B[k][n] = W[n][k]: W's rows in shared memory are B's columns.
      [[unroll]] for (uint j = 0; j < FN; ++j)
        coopMatLoad(w[j], sw, wb + j * 16 * LDS + kk, LDS, gl_CooperativeMatrixLayoutColumnMajor);
      [[unroll]] for (uint i = 0; i < FM; ++i)
        [[unroll]] for (uint j = 0; j < FN; ++j) acc[i * FN + j] = coopMatMulAdd(a[i], w[j], acc[i * FN + j]);
    }
    if (more) {
      const uint base = nxt * BM * LDS;
      [[unroll]] for (uint j = 0; j < PER; ++j) {
        sx[base + (lr + 8 * j) * LDS + lk] = float16_t(rx[j]);
        sw[base + (lr + 8 * j) * LDS + lk] = float16_t(rw[j]);
      }
    }
    barrier();
  }

  const uint st = sg * 256;
  [[unroll]] for (uint i = 0; i < FM; ++i)
    [[unroll]] for (uint j = 0; j < FN; ++j) {
      coopMatStore(acc[i * FN + j], stage, st, 16, gl_CooperativeMatrixLayoutRowMajor);
      subgroupMemoryBarrierShared();
      subgroupBarrier();
      const uint mb = m0 + sm * 64 + i * 16, nb = n0 + sn * 32 + j * 16;
      for (uint e = lane; e < 256; e += gl_SubgroupSize) {
        const uint m = mb + e / 16, n = nb + e % 16;
        if (m < p.M && n < p.N) store_output(b, m, n, stage[st + e]);
      }
      subgroupMemoryBarrierShared();
      subgroupBarrier();  // every lane read the block before the next fragment overwrites it
    }
}
