#version 450
#extension GL_GOOGLE_include_directive : require
// Non-finite scan for ops::NonFiniteCheck: counts the NaN and ±Inf elements of an f32 range and keeps the
// smallest (global) index of one in the result slot. Invocation g tests vec4s g, g + G, g + 2G, … (G
// invocations in all: neighbouring lanes read neighbouring vec4s) with a branch-free test of the exponent bits
// (all ones = NaN or Inf); only when that finds something does it re-read them element by element for the count
// and the first index. A clean tensor costs one read of its bytes and no atomics.
// nn/nonfinite reads the range through a storage buffer; its variant nn/nonfinite_tex4 (TEXEL,
// shaders/variants.cmake) through a uniform texel buffer (RGBA32UI), ~3x cheaper per load on CPU drivers.
// LOAD4(k): the k-th vec4 of the range's f32 bits as a uvec4 (the storage view is rounded up to 16 bytes:
// views are at least 64-byte aligned, the padding lies inside the allocation).
#ifdef TEXEL
#extension GL_EXT_samplerless_texture_functions : require
#endif

layout(local_size_x = 64) in;

#ifdef TEXEL
layout(binding = 0) uniform utextureBuffer xt;
#define LOAD4(k) texelFetch(xt, int(k))
#else
layout(std430, binding = 0) readonly buffer X { uvec4 x[]; };
#define LOAD4(k) x[k]
#endif

#include "index.glsl"

const uint EXP = 0x7f800000u;

layout(std430, binding = 1) buffer R { uint result[]; };  // per slot: count, first index (0xffffffff = none)

layout(push_constant) uniform Push { uint n, base, slot; } p;  // elements in this range, its first global index

void main() {
  uint g = flat_index();
  uint G = gl_NumWorkGroups.x * gl_NumWorkGroups.y * gl_WorkGroupSize.x;
  uint n4 = (p.n + 3u) / 4u;  // the last vec4 may reach past n: those lanes are excluded in the exact pass
  if (g >= n4) return;
  uvec4 gap = uvec4(1u);  // component-wise min of (bits & EXP) ^ EXP: 0 where an element was NaN or Inf
  for (uint k = g; k < n4; k += G) gap = min(gap, (LOAD4(k) & EXP) ^ EXP);
  if (all(notEqual(gap, uvec4(0u)))) return;
  uint count = 0u, first = 0xffffffffu;
  for (uint k = g; k < n4; k += G) {
    uvec4 v = LOAD4(k);
    for (uint j = 0u; j < 4u; ++j) {
      uint i = k * 4u + j;
      if (i < p.n && (v[j] & EXP) == EXP) {
        count++;
        first = min(first, i);
      }
    }
  }
  if (count > 0u) {
    atomicAdd(result[p.slot * 2u], count);
    atomicMin(result[p.slot * 2u + 1u], p.base + first);
  }
}
