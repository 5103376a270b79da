#version 450
#extension GL_GOOGLE_include_directive : require
// nn/cast (two elements per step, any count) and its variant nn/cast_x8 (X8, shaders/variants.cmake: eight
// elements per step as whole uvec4 loads/stores, counts that are multiples of 8). SRC/DST: 0 f32, 1 f16, 2 bf16, 3 i32. Narrowing to
// f16/bf16 rounds to nearest even in integer arithmetic (the same bits on every device; NaN stays NaN,
// overflow gives ±Inf); f32 -> i32 truncates toward zero, saturating, NaN -> 0. 16-bit data moves as whole
// 32-bit words (no 16-bit storage needed). With an odd count of 16-bit outputs the last word is shared with
// whatever follows the tensor: its other half is kept (atomic and/or).
#include "bf16.glsl"
#include "f16.glsl"

layout(constant_id = 0) const uint SRC = 0;
layout(constant_id = 1) const uint DST = 0;
layout(local_size_x = 64) in;
#ifdef X8
layout(std430, binding = 0) readonly buffer X { uvec4 x[]; };
layout(std430, binding = 1) writeonly buffer Y { uvec4 y[]; };
#else
layout(std430, binding = 0) readonly buffer X { uint x[]; };
layout(std430, binding = 1) buffer Y { uint y[]; };
#endif
layout(push_constant) uniform Push { uint n; } p;  // elements

const bool SRC16 = SRC == 1u || SRC == 2u, DST16 = DST == 1u || DST == 2u;

float decode(uint bits) {
  if (SRC == 0u) return uintBitsToFloat(bits);
  if (SRC == 1u) return f16_bits_to_f32(bits);
  if (SRC == 2u) return uintBitsToFloat(bits << 16);
  return float(int(bits));
}

uint encode(float v) {
  if (DST == 0u) return floatBitsToUint(v);
  if (DST == 1u) return f32_to_f16_bits(v);
  if (DST == 2u) return f32_to_bf16_bits(v);
  if (isnan(v)) return 0u;
  return uint(int(clamp(v, -2147483648.0, 2147483520.0)));
}

uint convert(uint bits) { return encode(decode(bits)); }
uint convert_pair(uint w) { return convert(w & 0xffffu) | (convert(w >> 16) << 16); }  // 16 -> 16

#ifdef X8
// Eight elements: two uvec4 on a 32-bit side, one uvec4 on a 16-bit side.
void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  uint groups = p.n / 8u;
  for (uint k = gl_GlobalInvocationID.x; k < groups; k += stride) {
    if (SRC16 && DST16) {
      uvec4 w = x[k];
      y[k] = uvec4(convert_pair(w.x), convert_pair(w.y), convert_pair(w.z), convert_pair(w.w));
    } else if (SRC16) {
      uvec4 w = x[k];
      y[2u * k] = uvec4(convert(w.x & 0xffffu), convert(w.x >> 16), convert(w.y & 0xffffu), convert(w.y >> 16));
      y[2u * k + 1u] = uvec4(convert(w.z & 0xffffu), convert(w.z >> 16), convert(w.w & 0xffffu), convert(w.w >> 16));
    } else if (DST16) {
      uvec4 a = x[2u * k], b = x[2u * k + 1u];
      y[k] = uvec4(convert(a.x) | (convert(a.y) << 16), convert(a.z) | (convert(a.w) << 16),
                   convert(b.x) | (convert(b.y) << 16), convert(b.z) | (convert(b.w) << 16));
    } else {
      uvec4 a = x[2u * k], b = x[2u * k + 1u];
      y[2u * k] = uvec4(convert(a.x), convert(a.y), convert(a.z), convert(a.w));
      y[2u * k + 1u] = uvec4(convert(b.x), convert(b.y), convert(b.z), convert(b.w));
    }
  }
}
#else
void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  uint pairs = (p.n + 1u) / 2u;
  for (uint k = gl_GlobalInvocationID.x; k < pairs; k += stride) {
    uint e = 2u * k;
    bool both = e + 1u < p.n;
    uint lo_bits, hi_bits = 0u;
    if (SRC16) {
      uint w = x[k];
      lo_bits = w & 0xffffu;
      hi_bits = w >> 16;
    } else {
      lo_bits = x[e];
      if (both) hi_bits = x[e + 1u];
    }
    uint lo = encode(decode(lo_bits)), hi = encode(decode(hi_bits));
    if (DST16) {
      if (both) {
        y[k] = lo | (hi << 16);
      } else {
        atomicAnd(y[k], 0xffff0000u);
        atomicOr(y[k], lo);
      }
    } else {
      y[e] = lo;
      if (both) y[e + 1u] = hi;
    }
  }
}
#endif
