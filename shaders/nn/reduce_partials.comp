#version 450
// First level of a two-level reduction over "segments" (a channel, a GroupNorm group, a whole tensor).
// Element j of segment s lives at s*seg_stride + (j / inner)*outer_stride + (j % inner); each workgroup
// reduces one block of block_len consecutive j of one segment (workgroup y = segment, x = block) and
// writes one partial pair: MODE 0 (sum, 0), MODE 1 (max, 0), MODE 2 (block mean, sum of squared
// deviations from it) computed two-pass, so reduce_merge.comp can combine blocks exactly (Chan et al.).
// VEC4 (inner, strides, seg_len and block_len multiples of 4): vec4 loads, and the block (4 vec4 per
// invocation for the default 1024; few enough not to spill) stays in registers between the two passes.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require

layout(local_size_x = 64) in;
const uint LOCAL = 64, CACHE = 4;
layout(constant_id = 0) const uint MODE = 0;
layout(constant_id = 1) const bool VEC4 = false;

layout(std430, binding = 0) readonly buffer X { vec4 x4[]; };
layout(std430, binding = 1) writeonly buffer P { float partials[]; };

layout(push_constant) uniform Push {
  uint seg_len, inner, seg_stride, outer_stride, block_len, blocks;
} p;

shared float red[LOCAL];

float combine(float a, float b) { return MODE == 1 ? max(a, b) : a + b; }
float combine4(float a, vec4 v) { return MODE == 1 ? max(a, max(max(v.x, v.y), max(v.z, v.w))) : a + ((v.x + v.y) + (v.z + v.w)); }

float workgroup_reduce(float v) {
  uint t = gl_LocalInvocationID.x;
  red[t] = v;
  barrier();
  for (uint s = LOCAL / 2; s > 0; s >>= 1) {
    if (t < s) red[t] = combine(red[t], red[t + s]);
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
  const float identity = MODE == 1 ? uintBitsToFloat(0xff800000u) : 0.0;  // -inf for max
  float r0, r1 = 0.0;

  if (VEC4) {
    // j counts vec4s; element index 4j.
    uint b4 = begin >> 2, e4 = end >> 2;
    vec4 cache[CACHE];
    float a = identity;
    [[unroll]] for (uint k = 0; k < CACHE; ++k) {
      uint j = b4 + t + k * LOCAL;
      cache[k] = j < e4 ? x4[address(seg, 4 * j) >> 2] : vec4(identity);
      a = combine4(a, cache[k]);
    }
    for (uint j = b4 + t + CACHE * LOCAL; j < e4; j += LOCAL) a = combine4(a, x4[address(seg, 4 * j) >> 2]);
    r0 = workgroup_reduce(a);
    if (MODE == 2) {
      float mean = r0 / float(end - begin);
      float q = 0.0;
      [[unroll]] for (uint k = 0; k < CACHE; ++k) {
        vec4 d = cache[k] - mean;
        if (b4 + t + k * LOCAL < e4) q += dot(d, d);
      }
      for (uint j = b4 + t + CACHE * LOCAL; j < e4; j += LOCAL) {
        vec4 d = x4[address(seg, 4 * j) >> 2] - mean;
        q += dot(d, d);
      }
      r1 = workgroup_reduce(q);
      r0 = mean;
    }
  } else {
    float a = identity;
    for (uint j = begin + t; j < end; j += LOCAL) {
      uint at = address(seg, j);
      a = combine(a, x4[at >> 2][at & 3u]);
    }
    r0 = workgroup_reduce(a);
    if (MODE == 2) {
      float mean = r0 / float(end - begin);
      float q = 0.0;
      for (uint j = begin + t; j < end; j += LOCAL) {
        uint at = address(seg, j);
        float d = x4[at >> 2][at & 3u] - mean;
        q += d * d;
      }
      r1 = workgroup_reduce(q);
      r0 = mean;
    }
  }
  if (t == 0) {
    uint at = (seg * p.blocks + blk) * 2;
    partials[at] = r0;
    partials[at + 1] = r1;
  }
}
