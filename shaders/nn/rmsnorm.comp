#version 450
// RMSNorm (T5LayerNorm) over the last dimension of x [rows, D]: y = weight * x / sqrt(mean(x^2) + eps), no
// mean subtraction, fp32 statistics. One workgroup per row; weight stored f32/bf16/f16. x and y may alias.
#extension GL_GOOGLE_include_directive : require

layout(local_size_x_id = 0) in;
layout(constant_id = 0) const uint LOCAL = 64;  // power of two
layout(constant_id = 1) const uint WDTYPE = 0;  // 0 f32, 1 bf16, 2 f16

layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(std430, binding = 2) readonly buffer W { uint w[]; };

layout(push_constant) uniform Push { uint rows, D; float eps; } p;

float load_w(uint i) {
  if (WDTYPE == 0) return uintBitsToFloat(w[i]);
  uint word = w[i >> 1];
  uint half_bits = (i & 1u) != 0u ? (word >> 16) : (word & 0xffffu);
  if (WDTYPE == 1) return uintBitsToFloat(half_bits << 16);
  return unpackHalf2x16(half_bits).x;
}

shared float red[LOCAL];

void main() {
  uint row = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  if (row >= p.rows) return;  // uniform per workgroup
  uint t = gl_LocalInvocationID.x;
  uint base = row * p.D;

  float s = 0.0;
  for (uint i = t; i < p.D; i += LOCAL) {
    float v = x[base + i];
    s += v * v;
  }
  red[t] = s;
  barrier();
  for (uint h = LOCAL / 2; h > 0; h >>= 1) {
    if (t < h) red[t] += red[t + h];
    barrier();
  }
  float rstd = inversesqrt(red[0] / float(p.D) + p.eps);
  for (uint i = t; i < p.D; i += LOCAL) y[base + i] = load_w(i) * (x[base + i] * rstd);
}
