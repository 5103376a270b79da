#version 450
// Dtype conversion, two elements per invocation so 16-bit data moves as whole 32-bit words (no 16-bit
// storage needed). SRC/DST: 0 f32, 1 f16, 2 bf16, 3 i32. Narrowing to f16/bf16 rounds to nearest even in
// integer arithmetic (the same bits on every device; NaN stays NaN, overflow gives ±Inf); f32 -> i32
// truncates toward zero, saturating, NaN -> 0. With an odd count of 16-bit outputs the last word is shared
// with whatever follows the tensor: its other half is kept (atomic and/or).
#extension GL_GOOGLE_include_directive : require
#include "bf16.glsl"

layout(constant_id = 0) const uint SRC = 0;
layout(constant_id = 1) const uint DST = 0;
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer X { uint x[]; };
layout(std430, binding = 1) buffer Y { uint y[]; };
layout(push_constant) uniform Push { uint n; } p;  // elements

float f16_bits_to_f32(uint h) {
  uint sign = (h & 0x8000u) << 16, e = (h >> 10) & 0x1fu, m = h & 0x3ffu;
  if (e == 0u) return uintBitsToFloat(sign | floatBitsToUint(float(m) * (1.0 / 16777216.0)));  // subnormal: exact
  if (e == 31u) return uintBitsToFloat(sign | 0x7f800000u | (m << 13));
  return uintBitsToFloat(sign | ((e + 112u) << 23) | (m << 13));
}

uint f32_to_f16_bits(float f) {
  uint u = floatBitsToUint(f);
  uint sign = (u >> 16) & 0x8000u, a = u & 0x7fffffffu;
  if (a > 0x7f800000u) return sign | 0x7e00u | ((a >> 13) & 0x3ffu);  // NaN, quiet
  if (a >= 0x477ff000u) return sign | 0x7c00u;                      // ≥ 65520 rounds to Inf
  if (a >= 0x38800000u) {                                           // normal half (≥ 2^-14)
    uint r = a - 0x38000000u;                                       // rebias 127 -> 15
    return sign | ((r + 0xfffu + ((r >> 13) & 1u)) >> 13);
  }
  if (a <= 0x33000000u) return sign;                                // ≤ 2^-25: ties to even give 0
  uint e = a >> 23, m = (a & 0x7fffffu) | 0x800000u;
  uint shift = 126u - e;                                            // 14..24: to units of 2^-24
  uint q = m >> shift, rem = m & ((1u << shift) - 1u), half_ = 1u << (shift - 1u);
  if (rem > half_ || (rem == half_ && (q & 1u) != 0u)) q += 1u;
  return sign | q;
}

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

void main() {
  uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
  uint pairs = (p.n + 1u) / 2u;
  for (uint k = gl_GlobalInvocationID.x; k < pairs; k += stride) {
    uint e = 2u * k;
    bool both = e + 1u < p.n;
    uint lo_bits, hi_bits = 0u;
    if (SRC == 1u || SRC == 2u) {
      uint w = x[k];
      lo_bits = w & 0xffffu;
      hi_bits = w >> 16;
    } else {
      lo_bits = x[e];
      if (both) hi_bits = x[e + 1u];
    }
    uint lo = encode(decode(lo_bits)), hi = encode(decode(hi_bits));
    if (DST == 1u || DST == 2u) {
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
