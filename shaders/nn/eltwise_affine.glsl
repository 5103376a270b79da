// Body of nn/eltwise_affine and nn/eltwise_affine_vec4: z = x·(s + s_offset) + t, with s and t broadcast
// over x alike as s[(e / inner) % C] (same rule as eltwise_binary.glsl): per-channel AdaIN-style
// normalisation, adaLN modulation x·(1 + scale) + shift over rows, or plain same-shape FMA. z may alias x.
// VEC4: x and z as vec4 (count a multiple of 4), s and t read per component (one value when inner % 4 == 0).
layout(local_size_x = 64) in;
#ifdef VEC4
#define T vec4
#else
#define T float
#endif
layout(std430, binding = 0) readonly buffer X { T x[]; };
layout(std430, binding = 1) readonly buffer S { float s[]; };
layout(std430, binding = 2) readonly buffer Tb { float t[]; };
layout(std430, binding = 3) writeonly buffer Z { T z[]; };
layout(push_constant) uniform Push {
  uint n;      // in units of T
  uint C;      // broadcast period of s and t, in elements
  uint inner;  // elements of x per s/t element
  float s_offset;
  uint span;   // items per workgroup (a multiple of 64)
} p;

void main() {
  uint begin = gl_WorkGroupID.x * p.span, end = min(begin + p.span, p.n);
  for (uint i = begin + gl_LocalInvocationID.x; i < end; i += gl_WorkGroupSize.x) {
#ifdef VEC4
    uint e = i * 4u;
    vec4 sv, tv;
    if (p.inner % 4u == 0u) {
      uint j = (e / p.inner) % p.C;
      sv = vec4(s[j]);
      tv = vec4(t[j]);
    } else {
      uvec4 j = ((uvec4(e) + uvec4(0u, 1u, 2u, 3u)) / p.inner) % p.C;
      sv = vec4(s[j.x], s[j.y], s[j.z], s[j.w]);
      tv = vec4(t[j.x], t[j.y], t[j.z], t[j.w]);
    }
    z[i] = x[i] * (sv + p.s_offset) + tv;
#else
    uint j = (i / p.inner) % p.C;
    z[i] = x[i] * (s[j] + p.s_offset) + t[j];
#endif
  }
}
