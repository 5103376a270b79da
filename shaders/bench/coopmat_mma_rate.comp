#version 450
#extension GL_EXT_control_flow_attributes : require
#extension GL_EXT_shader_explicit_arithmetic_types_float16 : require
#extension GL_KHR_memory_scope_semantics : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_cooperative_matrix : require
// Peak tensor-core rate probe: each subgroup runs `iterations` rounds of 4 independent coopMatMulAdd chains
// (16 x CK fp16 A, CK x 16 fp16 B, 16 x 16 fp32 accumulators) on registers only, then stores the 4
// accumulators once. Spec constant 0: CK (the device's coopmat K, 16 or 8). Push constant: uint iterations.
// Binding 0: f32 output, (workgroups x gl_NumSubgroups x 4 x 256) floats. FLOPs per dispatch =
// workgroups x (256 / subgroup size) x iterations x 4 x 2·16·16·CK.
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint CK = 16;
layout(push_constant) uniform Push { uint iterations; } p;
layout(std430, binding = 0) writeonly buffer Out { float o[]; };

void main() {
  coopmat<float16_t, gl_ScopeSubgroup, 16, CK, gl_MatrixUseA> a =
      coopmat<float16_t, gl_ScopeSubgroup, 16, CK, gl_MatrixUseA>(float16_t(1.0 / 1024.0));
  coopmat<float16_t, gl_ScopeSubgroup, CK, 16, gl_MatrixUseB> w =
      coopmat<float16_t, gl_ScopeSubgroup, CK, 16, gl_MatrixUseB>(float16_t(1.0 / 1024.0));
  coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator> c[4];
  [[unroll]] for (uint i = 0; i < 4; ++i)
    c[i] = coopmat<float, gl_ScopeSubgroup, 16, 16, gl_MatrixUseAccumulator>(float(i));
  for (uint it = 0; it < p.iterations; ++it)
    [[unroll]] for (uint i = 0; i < 4; ++i) c[i] = coopMatMulAdd(a, w, c[i]);
  const uint base = ((gl_WorkGroupID.x * gl_NumSubgroups) + gl_SubgroupID) * 4 * 256;
  [[unroll]] for (uint i = 0; i < 4; ++i)
    coopMatStore(c[i], o, base + i * 256, 16, gl_CooperativeMatrixLayoutRowMajor);
}
