#version 450
// RMSNorm (T5LayerNorm) over the last dimension of x [rows, D]: y = weight * (x / sqrt(mean(x^2) + eps)), no
// mean subtraction, fp32 statistics. One workgroup (or invocation) per row; weight stored f32/bf16/f16. x and y may alias.
// VEC4 (D multiple of 4): vec4 traffic and CACHE vec4 per invocation kept in registers (x read once).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require

layout(local_size_x_id = 0) in;
layout(constant_id = 0) const uint LOCAL = 64;  // power of two
layout(constant_id = 1) const uint WDTYPE = 0;  // 0 f32, 1 bf16, 2 f16
layout(constant_id = 2) const bool VEC4 = false;
layout(constant_id = 3) const uint CACHE = 1;   // host: ceil(D/4/LOCAL), at most 4
// One invocation per row instead of one workgroup (CPU drivers: no barriers; the row is read twice).
layout(constant_id = 4) const bool PER_INVOCATION = false;

layout(std430, binding = 0) readonly buffer X { vec4 x4[]; };
layout(std430, binding = 1) writeonly buffer Y { vec4 y4[]; };
layout(std430, binding = 2) readonly buffer W { uvec4 w4[]; };

// x_off: element offset of row 0 in the bound views (row chunks are bound from aligned-down offsets).
layout(push_constant) uniform Push { uint rows, D; float eps; uint x_off; } p;

#include "norm_weights.glsl"  // after WDTYPE
WEIGHT_LOADERS(load_w, w4)

shared float red[LOCAL];

float workgroup_sum(float v) {
  uint t = gl_LocalInvocationID.x;
  red[t] = v;
  barrier();
  for (uint s = LOCAL / 2; s > 0; s >>= 1) {
    if (t < s) red[t] += red[t + s];
    barrier();
  }
  return red[0];
}

float x1(uint i) { return x4[i >> 2][i & 3u]; }

// Compensated (Kahan) accumulation: O(1) rounding error for long rows summed by one invocation.
void kahan_add(inout vec4 sum, inout vec4 comp, vec4 v) {
  precise vec4 y = v - comp;
  precise vec4 t = sum + y;
  comp = (t - sum) - y;
  sum = t;
}

void row_per_invocation(uint row) {
  uint base = p.x_off + row * p.D;
  vec4 s = vec4(0.0), c = vec4(0.0);
  if (VEC4) {
    uint n4 = p.D >> 2, base4 = base >> 2;
    for (uint j = 0; j < n4; ++j) {
      vec4 v = x4[base4 + j];
      kahan_add(s, c, v * v);
    }
    float rstd = inversesqrt(((s.x + s.y) + (s.z + s.w)) / float(p.D) + p.eps);
    for (uint j = 0; j < n4; ++j) y4[base4 + j] = load_w4(j) * (x4[base4 + j] * rstd);
    return;
  }
  for (uint i = 0; i < p.D; ++i) kahan_add(s, c, vec4(x1(base + i) * x1(base + i), 0.0, 0.0, 0.0));
  float rstd = inversesqrt(s.x / float(p.D) + p.eps);
  for (uint i = 0; i < p.D; ++i) y4[(base + i) >> 2][(base + i) & 3u] = load_w1(i) * (x1(base + i) * rstd);
}

void main() {
  if (PER_INVOCATION) {
    uint r = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * LOCAL + gl_LocalInvocationID.x;
    if (r < p.rows) row_per_invocation(r);
    return;
  }
  uint row = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  if (row >= p.rows) return;  // uniform per workgroup
  uint t = gl_LocalInvocationID.x;
  uint base = p.x_off + row * p.D;

  if (VEC4) {
    uint n4 = p.D >> 2, base4 = base >> 2;
    vec4 cache[CACHE];
    float s = 0.0;
    [[unroll]] for (uint k = 0; k < CACHE; ++k) {
      uint j = t + k * LOCAL;
      cache[k] = j < n4 ? x4[base4 + j] : vec4(0.0);
      s += dot(cache[k], cache[k]);
    }
    for (uint j = t + CACHE * LOCAL; j < n4; j += LOCAL) {
      vec4 v = x4[base4 + j];
      s += dot(v, v);
    }
    float rstd = inversesqrt(workgroup_sum(s) / float(p.D) + p.eps);
    [[unroll]] for (uint k = 0; k < CACHE; ++k) {
      uint j = t + k * LOCAL;
      if (j < n4) y4[base4 + j] = load_w4(j) * (cache[k] * rstd);
    }
    for (uint j = t + CACHE * LOCAL; j < n4; j += LOCAL) y4[base4 + j] = load_w4(j) * (x4[base4 + j] * rstd);
    return;
  }

  float s = 0.0;
  for (uint i = t; i < p.D; i += LOCAL) {
    float v = x4[(base + i) >> 2][(base + i) & 3u];
    s += v * v;
  }
  float rstd = inversesqrt(workgroup_sum(s) / float(p.D) + p.eps);
  for (uint i = t; i < p.D; i += LOCAL)
    y4[(base + i) >> 2][(base + i) & 3u] = load_w1(i) * (x4[(base + i) >> 2][(base + i) & 3u] * rstd);
}
