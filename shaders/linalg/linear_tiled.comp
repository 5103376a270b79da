#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
// Linear layer Y = epilogue(X·Wᵀ), the "tiled" family (GPUs without tensor cores; the tested twin of
// linear_coopmat.comp): storage buffers, fp32 FMA. A workgroup computes a BM x BN tile of Y; each K step
// stages X[BM x BK] and W[BN x BK] (16-bit weights widened as loaded) in shared memory, k-major so that the
// product loop reads rows and columns as broadcasts / consecutive words; each invocation accumulates a
// TM x TN register block over rows ty + i·(BM/TM) and columns tx + j·(BN/TN) (interleaved: the stores of
// neighbouring invocations are neighbouring columns). Element loads are guarded and zero-filled, so any M,
// N, K, stride and offset works. Epilogue and bindings: linear_storage_io.glsl.
#include "linear_storage_io.glsl"

layout(local_size_x_id = 6) in;  // = (BM / TM) * (BN / TN), set by the host
layout(constant_id = 0) const uint BM = 64;  // tile rows (Y rows per workgroup)
layout(constant_id = 1) const uint BN = 64;  // tile columns
layout(constant_id = 3) const uint BK = 16;  // K values staged per step
layout(constant_id = 4) const uint TM = 4;   // register block rows per invocation
layout(constant_id = 5) const uint TN = 4;   // register block columns per invocation

const uint GX = BN / TN, GY = BM / TM, THREADS = GX * GY;
const uint LDX = BM + 1, LDW = BN + 1;  // +1: the k-major stores of consecutive k hit different banks
shared float sx[BK * LDX];
shared float sw[BK * LDW];

void main() {
  const uint t = gl_LocalInvocationIndex, tx = t % GX, ty = t / GX;
  const uint b = gl_WorkGroupID.z, m0 = gl_WorkGroupID.y * BM, n0 = gl_WorkGroupID.x * BN;

  float acc[TM][TN];
  [[unroll]] for (uint i = 0; i < TM; ++i)
    [[unroll]] for (uint j = 0; j < TN; ++j) acc[i][j] = 0.0;

  for (uint k0 = 0; k0 < p.K; k0 += BK) {
    // Consecutive invocations load consecutive k of one row (coalesced runs of BK elements).
    for (uint i = t; i < BM * BK; i += THREADS) sx[(i % BK) * LDX + i / BK] = load_x(b, m0 + i / BK, k0 + i % BK);
    for (uint i = t; i < BN * BK; i += THREADS) sw[(i % BK) * LDW + i / BK] = load_w(b, n0 + i / BK, k0 + i % BK);
    barrier();
    [[unroll]] for (uint k = 0; k < BK; ++k) {
      float xr[TM], wr[TN];
      [[unroll]] for (uint i = 0; i < TM; ++i) xr[i] = sx[k * LDX + ty + i * GY];
      [[unroll]] for (uint j = 0; j < TN; ++j) wr[j] = sw[k * LDW + tx + j * GX];
      [[unroll]] for (uint i = 0; i < TM; ++i)
        [[unroll]] for (uint j = 0; j < TN; ++j) acc[i][j] = fma(xr[i], wr[j], acc[i][j]);
    }
    barrier();
  }

  [[unroll]] for (uint i = 0; i < TM; ++i) {
    uint m = m0 + ty + i * GY;
    if (m >= p.M) continue;
    [[unroll]] for (uint j = 0; j < TN; ++j) {
      uint n = n0 + tx + j * GX;
      if (n < p.N) store_output(b, m, n, acc[i][j]);
    }
  }
}
