#version 450
#extension GL_KHR_cooperative_matrix : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
// Probe for tests (test_coopmat_smoke.cpp): one subgroup computes D = A*B + C with a single
// VK_KHR_cooperative_matrix multiply-add. A is MxK fp16 row-major, B KxN fp16 (row-major, or column-major
// when push.b_col_major: the layout of a transposed weight), C and D MxN fp32 row-major. The shape comes
// from specialization constants, so the test can run every shape the device lists.
layout(local_size_x_id = 0) in;  // the subgroup size: one subgroup per workgroup
layout(constant_id = 1) const uint M = 16;
layout(constant_id = 2) const uint N = 16;
layout(constant_id = 3) const uint K = 16;

layout(std430, binding = 0) readonly buffer A { float16_t a[]; };
layout(std430, binding = 1) readonly buffer B { float16_t b[]; };
layout(std430, binding = 2) readonly buffer C { float c[]; };
layout(std430, binding = 3) writeonly buffer D { float d[]; };
layout(push_constant) uniform Push { uint b_col_major; } p;

void main() {
  coopmat<float16_t, gl_ScopeSubgroup, M, K, gl_MatrixUseA> ma;
  coopmat<float16_t, gl_ScopeSubgroup, K, N, gl_MatrixUseB> mb;
  coopmat<float, gl_ScopeSubgroup, M, N, gl_MatrixUseAccumulator> mc;
  coopMatLoad(ma, a, 0, K, gl_CooperativeMatrixLayoutRowMajor);
  // The layout operand must be a constant: two loads, picked by a uniform branch.
  if (p.b_col_major != 0u)
    coopMatLoad(mb, b, 0, K, gl_CooperativeMatrixLayoutColumnMajor);
  else
    coopMatLoad(mb, b, 0, N, gl_CooperativeMatrixLayoutRowMajor);
  coopMatLoad(mc, c, 0, N, gl_CooperativeMatrixLayoutRowMajor);
  mc = coopMatMulAdd(ma, mb, mc);
  coopMatStore(mc, d, 0, N, gl_CooperativeMatrixLayoutRowMajor);
}
