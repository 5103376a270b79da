#version 450
#extension GL_GOOGLE_include_directive : require
// nn/eltwise_affine and its variants _vec4 and _tex4 (shaders/variants.cmake): z = x·(s + s_offset) + t,
// with s and t broadcast over x alike (eltwise_broadcast.glsl): per-channel AdaIN-style normalisation, adaLN
// modulation x·(1 + scale) + shift over rows, or a plain same-shape FMA. z may alias x.
// (none): one element per step, MODE 0 or 5. VEC4: x and z as vec4, s and t read per element, MODE 1..5 (0 is
// run as 1 with C = n). TEXEL: as VEC4 with x (RGBA32F), s and t read through texel buffers (RGBA32F for
// MODE 1, R32F otherwise).
layout(local_size_x = 64) in;
#if defined(VEC4) || defined(TEXEL)
#define T vec4
#else
#define T float
#endif
#ifdef TEXEL
#extension GL_EXT_samplerless_texture_functions : require  // textureBuffer + texelFetch: no combined sampler (SPIR-V 1.6)
layout(binding = 0) uniform textureBuffer x_tex;
layout(binding = 1) uniform textureBuffer s_tex;
layout(binding = 2) uniform textureBuffer t_tex;
#define LOAD_X(i) texelFetch(x_tex, int(i))
#define S1(j) texelFetch(s_tex, int(j)).x
#define T1(j) texelFetch(t_tex, int(j)).x
#else
layout(std430, binding = 0) readonly buffer X { T x[]; };
layout(std430, binding = 1) readonly buffer S { float s[]; };
layout(std430, binding = 2) readonly buffer Tb { float t[]; };
#define LOAD_X(i) x[i]
#define S1(j) s[j]
#define T1(j) t[j]
#endif
layout(std430, binding = 3) writeonly buffer Z { T z[]; };
layout(push_constant) uniform Push {
  uint n;      // in units of T
  uint C;      // broadcast period of s and t, in elements
  uint inner;  // elements of x per s/t element
  uint step_c, step_r;
  float s_offset;
  uint base;  // x's element 0 within the period of s and t (split chunks)
} p;

#include "eltwise_broadcast.glsl"

void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  uint i = gl_GlobalInvocationID.x;
#if defined(VEC4) || defined(TEXEL)
  Bcast b = bcast_start(i * 4u);
  for (; i < p.n; i += stride) {
    vec4 sv, tv;
    if (MODE == 1u) {
#ifdef TEXEL
      sv = texelFetch(s_tex, int(b.c / 4u));
      tv = texelFetch(t_tex, int(b.c / 4u));
#else
      sv = vec4(s[b.c], s[b.c + 1u], s[b.c + 2u], s[b.c + 3u]);
      tv = vec4(t[b.c], t[b.c + 1u], t[b.c + 2u], t[b.c + 3u]);
#endif
    } else if (MODE == 2u) {
      sv = vec4(S1(b.c));
      tv = vec4(T1(b.c));
    } else {
      uvec4 j = bcast_index4(b, i * 4u);
      sv = vec4(S1(j.x), S1(j.y), S1(j.z), S1(j.w));
      tv = vec4(T1(j.x), T1(j.y), T1(j.z), T1(j.w));
    }
    z[i] = LOAD_X(i) * (sv + p.s_offset) + tv;
    bcast_step(b);
  }
#else
  for (; i < p.n; i += stride) {
    uint j = MODE == 0u ? i : ((i + p.base) / p.inner) % p.C;
    z[i] = LOAD_X(i) * (S1(j) + p.s_offset) + T1(j);
  }
#endif
}
