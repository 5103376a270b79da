#version 450
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int32 : require
#extension GL_EXT_shader_16bit_storage : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_KHR_cooperative_matrix : require
#extension GL_NV_cooperative_matrix2 : require
// Linear layer Y = epilogue(X·Wᵀ) on tensor cores through VK_NV_cooperative_matrix2 (DeviceTuning::linear_coopmat2,
// where the device has workgroup-scope matrices with flexible dimensions and tensor addressing: NVIDIA's): the
// workgroup owns one BM x BN fp32 accumulator and, per K step of BK, loads X's BM x BK slice and W's BN x BK slice
// (read transposed as B) straight from memory with coopMatLoadTensorNV; the driver stages them through shared memory
// and feeds its tensor cores as it knows best (the KHR kernel, linalg/linear_coopmat.comp, does that by hand). The
// same products over the same fp16 operands with fp32 sums as that kernel, which is its twin on devices without
// coopmat2 (lavapipe among them: this shader is compiled and validated there, never run).
// X and W are fp16 as stored (the host takes this kernel only for fp16 X and W). Tensor layouts clamp to the
// matrices' bounds: loads past M, N or K read 0, stores past M or N are dropped, so any size works. A base offset
// must be 16-byte aligned: each matrix's is aligned down and the rest becomes a column offset of its slice.
// Epilogue: linear_epilogue.glsl's five steps per element (coopMatPerElementNV), then one tensor store to Y (f32, or
// f16 for the next GEMM's X where the host asks: Y_F16).
#include "linear_storage_io.glsl"
#include "gemm_tile_order.glsl"

layout(local_size_x_id = 4) in;            // WG: the invocations the device's workgroup-scope shape needs
layout(constant_id = 0) const uint BM = 128;  // output rows per workgroup
layout(constant_id = 1) const uint BN = 128;  // output columns
layout(constant_id = 3) const uint BK = 32;   // K per step
layout(constant_id = 11) const uint GROUP_M = 1;  // workgroup order (gemm_tile_order.glsl)
layout(constant_id = 14) const bool Y_F16 = false;

layout(std430, binding = 0) readonly buffer X16 { float16_t x16[]; };
layout(std430, binding = 1) readonly buffer W16 { float16_t w16[]; };
layout(std430, binding = 2) writeonly buffer Y16 { float16_t y16[]; };

// The epilogue of the element at (row, col) of the tile whose first output is (m0, n0) of batch item b.
float epilogue_element(const in uint32_t row, const in uint32_t col, const in float v, const in uint32_t b,
                       const in uint32_t m0, const in uint32_t n0) {
  const uint m = m0 + row, n = n0 + col;
  return m < p.M && n < p.N ? epilogue_value(b, m, n, v) : v;
}

void main() {
  const uvec2 tile = gemm_tile_order(GROUP_M);
  const uint b = gl_WorkGroupID.z, m0 = tile.x * BM, n0 = tile.y * BN;
  // Base offsets aligned down to 16 bytes (8 halves, 4 floats); the remainder shifts each slice's columns.
  const uint xe = p.x_off + b * p.x_bs, we = p.w_off + b * p.w_bs, ye = p.y_off + b * p.y_bs;
  const uint xr = xe & 7u, wr = we & 7u, yr = ye & (Y_F16 ? 7u : 3u);

  tensorLayoutNV<2, gl_CooperativeMatrixClampModeConstantNV> lx = createTensorLayoutNV(2, gl_CooperativeMatrixClampModeConstantNV);
  lx = setTensorLayoutDimensionNV(lx, p.M, p.K + xr);
  lx = setTensorLayoutStrideNV(lx, p.ldx, 1);
  tensorLayoutNV<2, gl_CooperativeMatrixClampModeConstantNV> lw = createTensorLayoutNV(2, gl_CooperativeMatrixClampModeConstantNV);
  lw = setTensorLayoutDimensionNV(lw, p.N, p.K + wr);
  lw = setTensorLayoutStrideNV(lw, p.ldw, 1);
  // B[k][n] = W[n][k]: W's slice read with its two dimensions swapped.
  tensorViewNV<2, false, 1, 0> transposed = createTensorViewNV(2, false, 1, 0);

  coopmat<float, gl_ScopeWorkgroup, BM, BN, gl_MatrixUseAccumulator> acc =
      coopmat<float, gl_ScopeWorkgroup, BM, BN, gl_MatrixUseAccumulator>(0.0);
  for (uint k = 0u; k < p.K; k += BK) {
    coopmat<float16_t, gl_ScopeWorkgroup, BM, BK, gl_MatrixUseA> a;
    coopmat<float16_t, gl_ScopeWorkgroup, BK, BN, gl_MatrixUseB> w;
    // Columns [k, k + BK) of the slice; those at or past K (+ the shift) read 0.
    coopMatLoadTensorNV(a, x16, xe - xr, sliceTensorLayoutNV(lx, m0, BM, k + xr, BK));
    coopMatLoadTensorNV(w, w16, we - wr, sliceTensorLayoutNV(lw, n0, BN, k + wr, BK), transposed);
    acc = coopMatMulAdd(a, w, acc);
  }

  coopmat<float, gl_ScopeWorkgroup, BM, BN, gl_MatrixUseAccumulator> out_tile;
  coopMatPerElementNV(out_tile, acc, epilogue_element, b, m0, n0);
  tensorLayoutNV<2, gl_CooperativeMatrixClampModeConstantNV> ly = createTensorLayoutNV(2, gl_CooperativeMatrixClampModeConstantNV);
  ly = setTensorLayoutDimensionNV(ly, p.M, p.N + yr);
  ly = setTensorLayoutStrideNV(ly, p.ldy, 1);
  ly = sliceTensorLayoutNV(ly, m0, BM, n0 + yr, BN);
  if (Y_F16) {
    coopmat<float16_t, gl_ScopeWorkgroup, BM, BN, gl_MatrixUseAccumulator> h =
        coopmat<float16_t, gl_ScopeWorkgroup, BM, BN, gl_MatrixUseAccumulator>(out_tile);
    coopMatStoreTensorNV(h, y16, ye - yr, ly);
  } else {
    coopMatStoreTensorNV(out_tile, y, ye - yr, ly);
  }
}
