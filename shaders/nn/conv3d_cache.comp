#version 450
#extension GL_GOOGLE_include_directive : require
// Causal conv cache update (CogVideoXCausalConv3d): the next cache is the last P frames of the time-padded
// input [prev (P frames) ; x (F frames)], where prev is the old cache or, without one, P copies of x's
// frame 0. One invocation owns all P slots of one (b, c, h, w) column and reads them all before writing,
// so the old and the new cache may be the same buffer. One dispatch covers the columns of (b, c) planes
// [bc0, bc0 + columns / ns) and plane elements [s0, s0 + ns), through sub-views of X, Prev and Next that
// start at elements x_base, prev_base and next_base.
layout(local_size_x = 64) in;
#include "index.glsl"  // after local_size: flat_index() reads gl_WorkGroupSize
layout(constant_id = 0) const uint MAXP = 4;  // upper bound on P (kernel time extent - 1)

layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) readonly buffer Prev { float prev[]; };
layout(std430, binding = 2) buffer Next { float next_cache[]; };

layout(push_constant) uniform Push {
  uint columns;  // B * C * H * W
  uint hw;       // H * W
  uint frames;   // F, frames of x
  uint prefix;   // P
  uint use_prev; // 0: the padding replicates x's frame 0
  uint bc0, s0, ns;
  uint x_base, prev_base, next_base;
  uint j0, nj;  // cache slots of this dispatch (in increasing order across dispatches: in place, slot j reads
                // old slot F + j > j, not yet overwritten)
} p;

void main() {
  uint i = flat_index();
  if (i >= p.columns) return;
  uint bc = p.bc0 + i / p.ns, s = p.s0 + i % p.ns;
  float v[MAXP];
  for (uint j = p.j0; j < p.j0 + p.nj; ++j) {
    uint t = p.frames + j;  // index on the padded axis of length P + F
    if (t >= p.prefix) v[j] = x[(bc * p.frames + t - p.prefix) * p.hw + s - p.x_base];
    else if (p.use_prev != 0) v[j] = prev[(bc * p.prefix + t) * p.hw + s - p.prev_base];
    else v[j] = x[bc * p.frames * p.hw + s - p.x_base];
  }
  for (uint j = p.j0; j < p.j0 + p.nj; ++j) next_cache[(bc * p.prefix + j) * p.hw + s - p.next_base] = v[j];
}
