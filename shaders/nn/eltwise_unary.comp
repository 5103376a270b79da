#version 450
#extension GL_GOOGLE_include_directive : require
// nn/eltwise_unary (float elements) and its variants (shaders/variants.cmake) nn/eltwise_unary_vec4 (VEC4:
// 4 elements per load/store, counts that are multiples of 4) and nn/eltwise_unary_tex4 (TEXEL: as VEC4 but x
// read through an RGBA32F texel buffer, ~2-3x faster than a storage-buffer load on lavapipe). y = f(x); y may be x itself (in place).
// OP 0: a·x + b (scale/shift); 1: SiLU; 2: GELU, tanh approximation (PyTorch approximate='tanh');
//    3: clamp(x, a, b); 4: GELU, exact erf form (PyTorch nn.GELU()).
#include "../common/erf.glsl"
layout(constant_id = 0) const uint OP = 0;
layout(local_size_x = 64) in;
#if defined(VEC4) || defined(TEXEL)
#define T vec4
#else
#define T float
#endif
#ifdef TEXEL
#extension GL_EXT_samplerless_texture_functions : require  // textureBuffer + texelFetch: no combined sampler (SPIR-V 1.6)
layout(binding = 0) uniform textureBuffer x_tex;
#define LOAD_X(i) texelFetch(x_tex, int(i))
#else
layout(std430, binding = 0) readonly buffer X { T x[]; };
#define LOAD_X(i) x[i]
#endif
layout(std430, binding = 1) writeonly buffer Y { T y[]; };
layout(push_constant) uniform Push {
  uint n;      // in units of T
  float a, b;
  uint first;  // first unit (the scalar tail after a vec4 body of an odd-sized tensor)
} p;

// tanh from one exp of a non-positive argument: never overflows (inf/inf) for large |u|.
T tanh_safe(T u) {
  T t = exp(-2.0 * abs(u));
  return sign(u) * (1.0 - t) / (1.0 + t);
}

T apply(T v) {
  if (OP == 0u) return p.a * v + p.b;
  if (OP == 1u) return v / (1.0 + exp(-v));
  if (OP == 2u) return 0.5 * v * (1.0 + tanh_safe(0.7978845608028654 * (v + 0.044715 * v * v * v)));
  if (OP == 4u) return gelu_erf(v);
  return clamp(v, p.a, p.b);
}

void main() {
  // Grid-stride loop over a bounded grid (measured faster on lavapipe than one contiguous span per group).
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  for (uint i = p.first + gl_GlobalInvocationID.x; i < p.n; i += stride) y[i] = apply(LOAD_X(i));
}
