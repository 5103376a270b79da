// fp16 <-> fp32 in integer arithmetic, rounding to nearest even (subnormals included; NaN stays NaN, quiet; overflow
// gives ±Inf): the same bits on every device, whatever rounding a driver's packHalf2x16 or matrix conversions use.
// A half is the low 16 bits of a uint.
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

// The value an fp16 holds after rounding v to nearest even, as an fp32, computed on the bits: a later conversion to
// fp16 (packHalf2x16, a cooperative matrix's) is then exact whatever its rounding. (float(float16_t(v)) did not make
// lavapipe's matrix conversion exact; this does.) Below 2^-14 fp16 steps by 2^-24 (subnormals); above 65504 it is
// inf. NaN is not expected (operands of products).
float f16_value(float v) {
  if (abs(v) < 6.103515625e-05) return roundEven(v * 16777216.0) * 5.9604644775390625e-08;
  uint b = floatBitsToUint(v);
  b = (b + 0xfffu + ((b >> 13) & 1u)) & ~0x1fffu;
  float r = uintBitsToFloat(b);
  return abs(r) > 65504.0 ? uintBitsToFloat((b & 0x80000000u) | 0x7f800000u) : r;
}
