#version 450
// LayerNorm over the last dimension of x [rows, D], one workgroup (or invocation) per row, fp32 two-pass statistics
// (mean, then mean of squared deviations) so large offsets do not cancel. Optional affine (weight, bias
// stored f32/bf16/f16) and optional adaLN modulation y = norm(x) * (1 + scale) + shift, where scale and
// shift are column slices of a per-batch table [B, table_stride]; rows are [B, L] tokens and tokens
// [0, split) use modulation set 0, tokens [split, L) set 1 (CogVideoXLayerNormZero: text, then video).
// x and y may be the same buffer: every element is read by the invocation that later writes it.
//
// Speed (memory-bound): with VEC4 (D, table stride and column offsets multiples of 4) everything moves as
// vec4; in the workgroup-per-row mapping each invocation keeps CACHE vec4 of its row in registers, so x is
// read from memory once.
// Buffers are declared as vec4 arrays; the scalar path (any D) indexes components.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require

layout(local_size_x_id = 0) in;
layout(constant_id = 0) const uint LOCAL = 64;      // power of two
layout(constant_id = 1) const uint WDTYPE = 0;      // weight/bias storage: 0 f32, 1 bf16, 2 f16
layout(constant_id = 2) const bool AFFINE = false;
layout(constant_id = 3) const bool MODULATE = false;
layout(constant_id = 4) const bool VEC4 = false;
// vec4 per invocation held in registers (host: ceil(D/4/LOCAL), at most 4): rows up to LOCAL*4*CACHE
// floats are read from memory once; the loops over it unroll exactly.
layout(constant_id = 5) const uint CACHE = 1;
// One invocation per row instead of one workgroup (CPU drivers: barriers and shared memory cost more than
// re-reading a cache-hot row; the row is read three times and never exchanged between invocations).
layout(constant_id = 6) const bool PER_INVOCATION = false;
// y stored f16 (VEC4 only: four halves a store): the activation of a GEMM that runs on tensor cores, rounded
// once here (to nearest even, as the GEMM's own conversion of an f32 X) instead of in every GEMM tile's loads.
layout(constant_id = 7) const bool Y_F16 = false;

layout(std430, binding = 0) readonly buffer X { vec4 x4[]; };
layout(std430, binding = 1) writeonly buffer Y { vec4 y4[]; };
layout(std430, binding = 1) writeonly buffer Yh { uvec2 yh4[]; };  // Y_F16: 4 halves per element
layout(std430, binding = 2) readonly buffer W { uvec4 w4[]; };
layout(std430, binding = 3) readonly buffer B { uvec4 b4[]; };
layout(std430, binding = 4) readonly buffer M { vec4 table4[]; };

layout(push_constant) uniform Push {
  uint rows, D;
  float eps;
  uint L, split, table_stride;
  uint shift0, scale0, shift1, scale1;  // column offsets into a table row
  // Row chunks (one dispatch per binding-sized range of rows): row 0 of the bound x/y is row row0 of the
  // whole tensor, x_off elements into the views (aligned-down binding offset); the bound table starts at
  // table row table_row0, table_off elements into its view.
  uint row0, table_row0, table_off, x_off;
  uint y_off;  // the same for y's view (its own alignment: y may be f16)
} p;

#include "norm_weights.glsl"  // after WDTYPE
WEIGHT_LOADERS(load_w, w4)
WEIGHT_LOADERS(load_b, b4)

float table1(uint i) { return table4[i >> 2][i & 3u]; }

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

// y's vec4 j of the row whose y starts at element ybase (a multiple of 4 on the VEC4 path).
void store4(uint ybase, uint j, vec4 xv, float mean, float rstd, uint scale_at, uint shift_at) {
  vec4 v = (xv - mean) * rstd;
  if (AFFINE) v = v * load_w4(j) + load_b4(j);
  if (MODULATE) v = v * (1.0 + table4[(scale_at >> 2) + j]) + table4[(shift_at >> 2) + j];
  if (Y_F16) {
    yh4[(ybase >> 2) + j] = uvec2(packHalf2x16(v.xy), packHalf2x16(v.zw));
  } else {
    y4[(ybase >> 2) + j] = v;
  }
}

float x1(uint i) { return x4[i >> 2][i & 3u]; }

void modulation_offsets(uint row, out uint scale_at, out uint shift_at) {
  scale_at = 0;
  shift_at = 0;
  if (MODULATE) {
    uint global = p.row0 + row, batch = global / p.L, token = global - batch * p.L;
    bool first_set = token < p.split;
    uint at = p.table_off + (batch - p.table_row0) * p.table_stride;
    scale_at = at + (first_set ? p.scale0 : p.scale1);
    shift_at = at + (first_set ? p.shift0 : p.shift1);
  }
}

// Compensated (Kahan) accumulation: a row of thousands of values summed serially by one invocation keeps
// O(1) rounding error instead of O(D), so large offsets stay exact as in the tree-reduced path.
void kahan_add(inout vec4 sum, inout vec4 comp, vec4 v) {
  precise vec4 y = v - comp;
  precise vec4 t = sum + y;
  comp = (t - sum) - y;
  sum = t;
}
float hsum(vec4 v) { return (v.x + v.y) + (v.z + v.w); }

void row_per_invocation(uint row) {
  uint base = p.x_off + row * p.D, scale_at, shift_at;
  modulation_offsets(row, scale_at, shift_at);
  vec4 s = vec4(0.0), c = vec4(0.0);
  if (VEC4) {
    uint n4 = p.D >> 2, base4 = base >> 2;
    for (uint j = 0; j < n4; ++j) kahan_add(s, c, x4[base4 + j]);
    float mean = hsum(s) / float(p.D);
    vec4 q = vec4(0.0);
    c = vec4(0.0);
    for (uint j = 0; j < n4; ++j) {
      vec4 d = x4[base4 + j] - mean;
      kahan_add(q, c, d * d);
    }
    float rstd = inversesqrt(hsum(q) / float(p.D) + p.eps);
    for (uint j = 0; j < n4; ++j) store4(p.y_off + row * p.D, j, x4[base4 + j], mean, rstd, scale_at, shift_at);
    return;
  }
  for (uint i = 0; i < p.D; ++i) kahan_add(s, c, vec4(x1(base + i), 0.0, 0.0, 0.0));
  float mean = s.x / float(p.D);
  vec4 q = vec4(0.0);
  c = vec4(0.0);
  for (uint i = 0; i < p.D; ++i) {
    float d = x1(base + i) - mean;
    kahan_add(q, c, vec4(d * d, 0.0, 0.0, 0.0));
  }
  float rstd = inversesqrt(q.x / float(p.D) + p.eps);
  for (uint i = 0; i < p.D; ++i) {
    float v = (x1(base + i) - mean) * rstd;
    if (AFFINE) v = v * load_w1(i) + load_b1(i);
    if (MODULATE) v = v * (1.0 + table1(scale_at + i)) + table1(shift_at + i);
    const uint yi = p.y_off + row * p.D + i;
    y4[yi >> 2][yi & 3u] = v;
  }
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

  uint scale_at, shift_at;
  modulation_offsets(row, scale_at, shift_at);

  if (VEC4) {
    uint n4 = p.D >> 2, base4 = base >> 2;
    vec4 cache[CACHE];
    float s = 0.0;
    [[unroll]] for (uint k = 0; k < CACHE; ++k) {
      uint j = t + k * LOCAL;
      cache[k] = j < n4 ? x4[base4 + j] : vec4(0.0);
      s += (cache[k].x + cache[k].y) + (cache[k].z + cache[k].w);
    }
    for (uint j = t + CACHE * LOCAL; j < n4; j += LOCAL) {
      vec4 v = x4[base4 + j];
      s += (v.x + v.y) + (v.z + v.w);
    }
    float mean = workgroup_sum(s) / float(p.D);
    float q = 0.0;
    [[unroll]] for (uint k = 0; k < CACHE; ++k) {
      vec4 d = cache[k] - mean;
      if (t + k * LOCAL < n4) q += dot(d, d);
    }
    for (uint j = t + CACHE * LOCAL; j < n4; j += LOCAL) {
      vec4 d = x4[base4 + j] - mean;
      q += dot(d, d);
    }
    float rstd = inversesqrt(workgroup_sum(q) / float(p.D) + p.eps);
    [[unroll]] for (uint k = 0; k < CACHE; ++k) {
      uint j = t + k * LOCAL;
      if (j < n4) store4(p.y_off + row * p.D, j, cache[k], mean, rstd, scale_at, shift_at);
    }
    for (uint j = t + CACHE * LOCAL; j < n4; j += LOCAL)
      store4(p.y_off + row * p.D, j, x4[base4 + j], mean, rstd, scale_at, shift_at);
    return;
  }

  float s = 0.0;
  for (uint i = t; i < p.D; i += LOCAL) s += x4[(base + i) >> 2][(base + i) & 3u];
  float mean = workgroup_sum(s) / float(p.D);
  float q = 0.0;
  for (uint i = t; i < p.D; i += LOCAL) {
    float d = x4[(base + i) >> 2][(base + i) & 3u] - mean;
    q += d * d;
  }
  float rstd = inversesqrt(workgroup_sum(q) / float(p.D) + p.eps);
  for (uint i = t; i < p.D; i += LOCAL) {
    float v = (x4[(base + i) >> 2][(base + i) & 3u] - mean) * rstd;
    if (AFFINE) v = v * load_w1(i) + load_b1(i);
    if (MODULATE) v = v * (1.0 + table1(scale_at + i)) + table1(shift_at + i);
    const uint yi = p.y_off + row * p.D + i;
    y4[yi >> 2][yi & 3u] = v;
  }
}
