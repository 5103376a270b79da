#version 450
// Second level of the two-level reduction: one workgroup per segment combines its block partials from
// reduce_partials.comp. MODE 0: out0 = sum. MODE 1: out0 = max. MODE 2: out0 = mean, out1 = population
// variance, merging (count, mean, M2) triples with Chan's pairwise formula (no cancellation of large sums).
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;
const uint LOCAL = 64;
layout(constant_id = 0) const uint MODE = 0;

layout(std430, binding = 0) readonly buffer P { float partials[]; };
layout(std430, binding = 1) writeonly buffer O0 { float out0[]; };
layout(std430, binding = 2) writeonly buffer O1 { float out1[]; };

// One workgroup per segment, the grid folded over x and y (groups past `segments` return).
layout(push_constant) uniform Push { uint seg_len, block_len, blocks, out_offset, segments; } p;

shared float s_n[LOCAL], s_a[LOCAL], s_b[LOCAL];

// (n, a, b) <- merge with (nb, ab, bb): counts, means, sums of squared deviations.
void chan_merge(inout float n, inout float a, inout float b, float nb, float ab, float bb) {
  float n2 = n + nb;
  if (nb == 0.0) return;
  float d = ab - a;
  float f = nb / n2;
  a += d * f;
  b += bb + d * d * n * f;
  n = n2;
}

void main() {
  uint seg = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  if (seg >= p.segments) return;  // the whole workgroup returns: no barrier is left half-reached
  uint t = gl_LocalInvocationID.x;
  float n = 0.0, a = MODE == 1 ? uintBitsToFloat(0xff800000u) : 0.0, b = 0.0;
  for (uint k = t; k < p.blocks; k += LOCAL) {
    uint at = (seg * p.blocks + k) * 2;
    float v = partials[at];
    if (MODE == 0) a += v;
    else if (MODE == 1) a = max(a, v);
    else chan_merge(n, a, b, float(min(p.block_len, p.seg_len - k * p.block_len)), v, partials[at + 1]);
  }
  s_n[t] = n;
  s_a[t] = a;
  s_b[t] = b;
  barrier();
  for (uint s = LOCAL / 2; s > 0; s >>= 1) {
    if (t < s) {
      if (MODE == 0) s_a[t] += s_a[t + s];
      else if (MODE == 1) s_a[t] = max(s_a[t], s_a[t + s]);
      else {
        float n1 = s_n[t], a1 = s_a[t], b1 = s_b[t];
        chan_merge(n1, a1, b1, s_n[t + s], s_a[t + s], s_b[t + s]);
        s_n[t] = n1;
        s_a[t] = a1;
        s_b[t] = b1;
      }
    }
    barrier();
  }
  if (t == 0) {
    out0[p.out_offset + seg] = s_a[0];
    if (MODE == 2) out1[p.out_offset + seg] = s_b[0] / float(p.seg_len);
  }
}
