#version 450
// Non-finite scan for ops::NonFiniteCheck: counts the NaN and ±Inf elements of an f32 range and keeps the
// smallest (global) index of one in the result slot. Each invocation scans RUN consecutive elements (the
// contiguous runs CPU drivers load fastest) and touches the result only when it found something, so a clean
// tensor costs one read of its bytes and no atomics.
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;
#include "index.glsl"  // after the local size: flat_index() reads gl_WorkGroupSize

const uint RUN = 16;

layout(std430, binding = 0) readonly buffer X { uint x[]; };  // the f32 bits: exponent all ones = NaN or Inf
layout(std430, binding = 1) buffer R { uint result[]; };      // per slot: count, first index (0xffffffff = none)

layout(push_constant) uniform Push { uint n, base, slot; } p;  // elements in this range, its first global index

void main() {
  uint start = flat_index() * RUN;
  if (start >= p.n) return;
  uint end = min(start + RUN, p.n);
  uint count = 0u, first = 0xffffffffu;
  for (uint i = start; i < end; ++i) {
    if ((x[i] & 0x7f800000u) == 0x7f800000u) {
      count++;
      first = min(first, i);
    }
  }
  if (count > 0u) {
    atomicAdd(result[p.slot * 2u], count);
    atomicMin(result[p.slot * 2u + 1u], p.base + first);
  }
}
