#version 450
// LayerNorm over the last dimension of x [rows, D], one workgroup per row, fp32 two-pass statistics
// (mean, then mean of squared deviations) so large offsets do not cancel. Optional affine (weight, bias
// stored f32/bf16/f16) and optional adaLN modulation y = norm(x) * (1 + scale) + shift, where scale and
// shift are column slices of a per-batch table [B, table_stride]; rows are [B, L] tokens and tokens
// [0, split) use modulation set 0, tokens [split, L) set 1 (CogVideoXLayerNormZero: text, then video).
// x and y may be the same buffer: every element is read by the invocation that later writes it.
#extension GL_GOOGLE_include_directive : require
#include "bf16.glsl"

layout(local_size_x_id = 0) in;
layout(constant_id = 0) const uint LOCAL = 64;      // power of two
layout(constant_id = 1) const uint WDTYPE = 0;      // weight/bias storage: 0 f32, 1 bf16, 2 f16
layout(constant_id = 2) const bool AFFINE = false;
layout(constant_id = 3) const bool MODULATE = false;

layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(std430, binding = 2) readonly buffer W { uint w[]; };
layout(std430, binding = 3) readonly buffer B { uint b[]; };
layout(std430, binding = 4) readonly buffer M { float table[]; };

layout(push_constant) uniform Push {
  uint rows, D;
  float eps;
  uint L, split, table_stride;
  uint shift0, scale0, shift1, scale1;  // column offsets into a table row
} p;

float unpack_weight(uint word, uint i) {
  if (WDTYPE == 0) return uintBitsToFloat(word);
  uint half_bits = (i & 1u) != 0u ? (word >> 16) : (word & 0xffffu);
  if (WDTYPE == 1) return uintBitsToFloat(half_bits << 16);
  return unpackHalf2x16(half_bits).x;
}
float load_w(uint i) { return unpack_weight(w[WDTYPE == 0 ? i : i >> 1], i); }
float load_b(uint i) { return unpack_weight(b[WDTYPE == 0 ? i : i >> 1], i); }

shared float red[LOCAL];

float workgroup_sum(float v) {
  uint t = gl_LocalInvocationID.x;
  red[t] = v;
  barrier();
  for (uint s = LOCAL / 2; s > 0; s >>= 1) {
    if (t < s) red[t] += red[t + s];
    barrier();
  }
  float r = red[0];
  barrier();
  return r;
}

void main() {
  uint row = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  if (row >= p.rows) return;  // uniform per workgroup
  uint t = gl_LocalInvocationID.x;
  uint base = row * p.D;

  float s = 0.0;
  for (uint i = t; i < p.D; i += LOCAL) s += x[base + i];
  float mean = workgroup_sum(s) / float(p.D);
  float q = 0.0;
  for (uint i = t; i < p.D; i += LOCAL) {
    float d = x[base + i] - mean;
    q += d * d;
  }
  float rstd = inversesqrt(workgroup_sum(q) / float(p.D) + p.eps);

  uint scale_at = 0, shift_at = 0;
  if (MODULATE) {
    uint batch = row / p.L, token = row - batch * p.L;
    bool first_set = token < p.split;
    scale_at = batch * p.table_stride + (first_set ? p.scale0 : p.scale1);
    shift_at = batch * p.table_stride + (first_set ? p.shift0 : p.shift1);
  }
  for (uint i = t; i < p.D; i += LOCAL) {
    float v = (x[base + i] - mean) * rstd;
    if (AFFINE) v = v * load_w(i) + load_b(i);
    if (MODULATE) v = v * (1.0 + table[scale_at + i]) + table[shift_at + i];
    y[base + i] = v;
  }
}
