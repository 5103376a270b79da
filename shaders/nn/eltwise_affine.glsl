// Body of nn/eltwise_affine, nn/eltwise_affine_vec4 and nn/eltwise_affine_tex4: z = x·(s + s_offset) + t,
// with s and t broadcast over x alike as s[(e / inner) % C] (same rule as eltwise_binary.glsl): per-channel
// AdaIN-style normalisation, adaLN modulation x·(1 + scale) + shift over rows, or plain same-shape FMA.
// z may alias x. VEC4: x and z as vec4 (count a multiple of 4), s and t read per component (one value when
// inner % 4 == 0). TEXEL: as VEC4 with x (RGBA32F), s and t (R32F) read through texel buffers.
layout(local_size_x = 64) in;
#if defined(VEC4) || defined(TEXEL)
#define T vec4
#else
#define T float
#endif
#ifdef TEXEL
layout(binding = 0) uniform samplerBuffer x_tex;
layout(binding = 1) uniform samplerBuffer s_tex;
layout(binding = 2) uniform samplerBuffer t_tex;
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
  float s_offset;
} p;

void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  for (uint i = gl_GlobalInvocationID.x; i < p.n; i += stride) {
#if defined(VEC4) || defined(TEXEL)
    uint e = i * 4u;
    vec4 sv, tv;
    if (p.inner % 4u == 0u) {
      uint j = (e / p.inner) % p.C;
      sv = vec4(S1(j));
      tv = vec4(T1(j));
    } else {
      uvec4 j = ((uvec4(e) + uvec4(0u, 1u, 2u, 3u)) / p.inner) % p.C;
      sv = vec4(S1(j.x), S1(j.y), S1(j.z), S1(j.w));
      tv = vec4(T1(j.x), T1(j.y), T1(j.z), T1(j.w));
    }
    z[i] = LOAD_X(i) * (sv + p.s_offset) + tv;
#else
    uint j = (i / p.inner) % p.C;
    z[i] = LOAD_X(i) * (S1(j) + p.s_offset) + T1(j);
#endif
  }
}
