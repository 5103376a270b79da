#version 450
// First level of a two-level reduction over "segments" (a channel, a GroupNorm group, a whole tensor).
// Element j of segment s lives at s*seg_stride + (j / inner)*outer_stride + (j % inner). Each invocation
// reduces one chunk of `chunk` consecutive j of one segment (workgroup y = segment) on its own -- no shared
// memory, no barriers, which dominate the cost on CPU drivers -- and writes one partial pair: MODE 0
// (sum, 0), MODE 1 (max, 0), MODE 2 (chunk mean, sum of squared deviations from it), two-pass over the
// chunk (re-read while it is cache-hot), so reduce_merge.comp combines chunks exactly (Chan et al.).
// VEC4 (inner, strides, seg_len and chunk multiples of 4): vec4 loads.
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;
layout(constant_id = 0) const uint MODE = 0;
layout(constant_id = 1) const bool VEC4 = false;

layout(std430, binding = 0) readonly buffer X { vec4 x4[]; };
layout(std430, binding = 1) writeonly buffer P { float partials[]; };

layout(push_constant) uniform Push {
  uint seg_len, inner, seg_stride, outer_stride, chunk, chunks;
  // A split call: this dispatch does chunks [c_first, c_end) of segments from seg_first, reading x through a
  // window that starts at element x_base.
  uint x_base, c_first, c_end, seg_first;
} p;

const uint STEP = VEC4 ? 4u : 1u;  // elements per load

// Walks j = begin, begin+STEP, ... < end of segment `seg`, tracking the address without a division per step.
struct Cursor {
  uint at, in_row;  // element address, position inside the current inner run
};
Cursor cursor_at(uint seg, uint j) {
  uint o = j / p.inner, i = j - o * p.inner;
  return Cursor(seg * p.seg_stride + o * p.outer_stride + i - p.x_base, i);
}
void advance(inout Cursor c) {
  c.at += STEP;
  c.in_row += STEP;
  if (c.in_row == p.inner) {
    c.in_row = 0;
    c.at += p.outer_stride - p.inner;
  }
}
vec4 load(Cursor c) { return VEC4 ? x4[c.at >> 2] : vec4(x4[c.at >> 2][c.at & 3u], 0.0, 0.0, 0.0); }

float combine(float a, vec4 v) {
  if (MODE == 1) return VEC4 ? max(a, max(max(v.x, v.y), max(v.z, v.w))) : max(a, v.x);
  return VEC4 ? a + ((v.x + v.y) + (v.z + v.w)) : a + v.x;
}

void main() {
  uint c = p.c_first + gl_GlobalInvocationID.x, seg = p.seg_first + gl_WorkGroupID.y;
  if (c >= p.c_end) return;
  uint begin = c * p.chunk, end = min(begin + p.chunk, p.seg_len);
  const Cursor start = cursor_at(seg, begin);

  float a = MODE == 1 ? uintBitsToFloat(0xff800000u) : 0.0;  // -inf for max
  Cursor cur = start;
  for (uint j = begin; j < end; j += STEP, advance(cur)) a = combine(a, load(cur));
  float r0 = a, r1 = 0.0;
  if (MODE == 2) {
    float mean = a / float(end - begin);
    float q = 0.0;
    cur = start;
    for (uint j = begin; j < end; j += STEP, advance(cur)) {
      vec4 d = load(cur) - mean;
      q += VEC4 ? dot(d, d) : d.x * d.x;
    }
    r0 = mean;
    r1 = q;
  }
  uint at = (seg * p.chunks + c) * 2;
  partials[at] = r0;
  partials[at + 1] = r1;
}
