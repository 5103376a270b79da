#version 450
#extension GL_GOOGLE_include_directive : require
// nn/eltwise_binary and its variants (shaders/variants.cmake): z = op(x, y) with y broadcast over x
// (eltwise_broadcast.glsl): same shape, a scalar, a row vector [D] over [rows, D] or a per-channel vector [C]
// over [outer, C, inner].
// z may alias x or y (in place). OP (constant 0): 0 z = alpha·x + beta·y (add, sub, axpby); 1 z = alpha·x·y.
// Variants: (none) one element per step, MODE 0 or 5; VEC4: x, y, z as vec4, MODE 0 or 1; VEC4 + Y_SCALAR:
// x, z as vec4 with y read per element, MODE 2..5; TEXEL: x (RGBA32F) and y read through texel buffers
// (~2-3x cheaper loads on lavapipe), y bound RGBA32F for MODE 0/1 and R32F otherwise, z as vec4.
layout(constant_id = 0) const uint OP = 0;
layout(local_size_x = 64) in;
#if defined(VEC4) || defined(TEXEL)
#define T vec4
#else
#define T float
#endif
#if defined(VEC4) && !defined(Y_SCALAR)
#define TY vec4
#else
#define TY float
#endif
#ifdef TEXEL
#extension GL_EXT_samplerless_texture_functions : require  // textureBuffer + texelFetch: no combined sampler (SPIR-V 1.6)
layout(binding = 0) uniform textureBuffer x_tex;
layout(binding = 1) uniform textureBuffer y_tex;
#define LOAD_X(i) texelFetch(x_tex, int(i))
#define LOAD_Y(j) texelFetch(y_tex, int(j))
#define Y1(j) texelFetch(y_tex, int(j)).x
#else
layout(std430, binding = 0) readonly buffer X { T x[]; };
layout(std430, binding = 1) readonly buffer Y { TY y[]; };
#define LOAD_X(i) x[i]
#define LOAD_Y(j) y[j]
#define Y1(j) y[j]
#endif
layout(std430, binding = 2) writeonly buffer Z { T z[]; };
layout(push_constant) uniform Push {
  uint n;       // in units of T
  uint C;       // broadcast period of y, in elements
  uint inner;   // elements of x per y element
  uint step_c, step_r;  // advance of (c, r) per grid stride
  float alpha, beta;
  uint base;  // x's element 0 within y's period (split chunks)
} p;

#include "eltwise_broadcast.glsl"

T combine(T a, T b) { return OP == 0u ? p.alpha * a + p.beta * b : p.alpha * a * b; }

void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  uint i = gl_GlobalInvocationID.x;
#if defined(VEC4) || defined(TEXEL)
  Bcast b = bcast_start(i * 4u);
  for (; i < p.n; i += stride) {
    T yv;
    if (MODE <= 1u) {
#if defined(TEXEL) || !defined(Y_SCALAR)
      yv = LOAD_Y(MODE == 0u ? i : b.c / 4u);
#endif
    } else {
#if defined(TEXEL) || defined(Y_SCALAR)
      uvec4 j = bcast_index4(b, i * 4u);
      yv = MODE == 2u ? vec4(Y1(j.x)) : vec4(Y1(j.x), Y1(j.y), Y1(j.z), Y1(j.w));
#endif
    }
    z[i] = combine(LOAD_X(i), yv);
    if (MODE != 0u) bcast_step(b);
  }
#else
  for (; i < p.n; i += stride) z[i] = combine(LOAD_X(i), MODE == 0u ? Y1(i) : Y1(((i + p.base) / p.inner) % p.C));
#endif
}
