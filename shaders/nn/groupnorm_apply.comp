#version 450
// GroupNorm, last step: y = (x - mean[g]) / sqrt(var[g] + eps) * gamma[c] + beta[c], optionally SiLU, on
// x [B, C, S] (S = F*H*W). Workgroup y = plane (b, c), x = a run of 64*ITEMS elements (vec4s with VEC4) of that plane, so the
// group statistics and the channel's affine are uniform per workgroup. Statistics come from
// reduce_partials/reduce_merge (mean and population variance per (b, group)). y may alias x.
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;
const uint LOCAL = 64, ITEMS = 16;
layout(constant_id = 0) const uint WDTYPE = 0;  // gamma/beta storage: 0 f32, 1 bf16, 2 f16
layout(constant_id = 1) const bool AFFINE = true;
layout(constant_id = 2) const bool SILU = false;
layout(constant_id = 3) const bool VEC4 = false;  // S multiple of 4: a workgroup covers 4*64*ITEMS elements

layout(std430, binding = 0) readonly buffer X { vec4 x4[]; };
layout(std430, binding = 1) writeonly buffer Y { vec4 y4[]; };
layout(std430, binding = 2) readonly buffer W { uint w[]; };
layout(std430, binding = 3) readonly buffer Bb { uint b[]; };
layout(std430, binding = 4) readonly buffer Mean { float mean[]; };
layout(std430, binding = 5) readonly buffer Var { float var[]; };

// A dispatch covers planes [plane0, plane0 + gl_NumWorkGroups.y), a run of len elements of each (the host
// splits x into binding-sized chunks: whole planes, or one plane's elements in runs); the bound views start
// x_off elements before the chunk's first element (aligned-down binding offset).
layout(push_constant) uniform Push { uint C, S, channels_per_group; float eps; uint plane0, x_off, len; } p;

float unpack_weight(uint word, uint i) {
  if (WDTYPE == 0) return uintBitsToFloat(word);
  uint half_bits = (i & 1u) != 0u ? (word >> 16) : (word & 0xffffu);
  if (WDTYPE == 1) return uintBitsToFloat(half_bits << 16);
  return unpackHalf2x16(half_bits).x;
}
float load_w(uint i) { return unpack_weight(w[WDTYPE == 0 ? i : i >> 1], i); }
float load_b(uint i) { return unpack_weight(b[WDTYPE == 0 ? i : i >> 1], i); }

void main() {
  uint local_plane = gl_WorkGroupID.y, plane = p.plane0 + local_plane;
  uint batch = plane / p.C, c = plane - batch * p.C;
  uint g = batch * (p.C / p.channels_per_group) + c / p.channels_per_group;
  float rstd = inversesqrt(var[g] + p.eps);
  // (x - mean) * (rstd * gamma) + beta: subtracting the mean first keeps large offsets exact.
  float mu = mean[g], k = rstd, m = 0.0;
  if (AFFINE) {
    k = rstd * load_w(c);
    m = load_b(c);
  }
  // Each invocation takes ITEMS consecutive units (vec4s with VEC4): contiguous per invocation is what CPU
  // drivers load fastest, and GPUs still see each workgroup cover one contiguous range.
  uint first = gl_WorkGroupID.x * (LOCAL * ITEMS) + gl_LocalInvocationID.x * ITEMS;
  uint base = p.x_off + local_plane * p.S;  // view element of the chunk's first element in this plane
  if (VEC4) {  // S, the chunk start and x_off are multiples of 4
    uint base4 = base >> 2, n4 = p.len >> 2;
    uint end = min(first + ITEMS, n4);
    for (uint i = first; i < end; ++i) {
      vec4 v = (x4[base4 + i] - mu) * k + m;
      if (SILU) v = v / (1.0 + exp(-v));
      y4[base4 + i] = v;
    }
    return;
  }
  uint end = min(first + ITEMS, p.len);
  for (uint i = first; i < end; ++i) {
    uint e = base + i;
    float v = (x4[e >> 2][e & 3u] - mu) * k + m;
    if (SILU) v = v / (1.0 + exp(-v));
    y4[e >> 2][e & 3u] = v;
  }
}
