#version 450
// First level of a two-level reduction over "segments" (a channel, a GroupNorm group, a whole tensor).
// Element j of segment s lives at s*seg_stride + (j / inner)*outer_stride + (j % inner); each workgroup
// reduces one block of block_len consecutive j of one segment (workgroup y = segment, x = block) and
// writes one partial pair: MODE 0 (sum, 0), MODE 1 (max, 0), MODE 2 (block mean, sum of squared
// deviations from it) computed two-pass, so reduce_merge.comp can combine blocks exactly (Chan et al.).
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;
const uint LOCAL = 64;
layout(constant_id = 0) const uint MODE = 0;

layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) writeonly buffer P { float partials[]; };

layout(push_constant) uniform Push {
  uint seg_len, inner, seg_stride, outer_stride, block_len, blocks;
} p;

shared float red[LOCAL];

float workgroup_reduce(float v) {
  uint t = gl_LocalInvocationID.x;
  red[t] = v;
  barrier();
  for (uint s = LOCAL / 2; s > 0; s >>= 1) {
    if (t < s) red[t] = MODE == 1 ? max(red[t], red[t + s]) : red[t] + red[t + s];
    barrier();
  }
  float r = red[0];
  barrier();
  return r;
}

uint address(uint seg, uint j) {
  if (p.inner >= p.seg_len) return seg * p.seg_stride + j;  // contiguous segment
  uint o = j / p.inner;
  return seg * p.seg_stride + o * p.outer_stride + (j - o * p.inner);
}

void main() {
  uint blk = gl_WorkGroupID.x, seg = gl_WorkGroupID.y;
  uint t = gl_LocalInvocationID.x;
  uint begin = blk * p.block_len;
  uint end = min(begin + p.block_len, p.seg_len);

  float a = MODE == 1 ? uintBitsToFloat(0xff800000u) : 0.0;  // -inf for max
  for (uint j = begin + t; j < end; j += LOCAL) {
    float v = x[address(seg, j)];
    a = MODE == 1 ? max(a, v) : a + v;
  }
  float r0 = workgroup_reduce(a);
  float r1 = 0.0;
  if (MODE == 2) {
    float mean = r0 / float(end - begin);
    float q = 0.0;
    for (uint j = begin + t; j < end; j += LOCAL) {
      float d = x[address(seg, j)] - mean;
      q += d * d;
    }
    r1 = workgroup_reduce(q);
    r0 = mean;
  }
  if (t == 0) {
    uint at = (seg * p.blocks + blk) * 2;
    partials[at] = r0;
    partials[at + 1] = r1;
  }
}
