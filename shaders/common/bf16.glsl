// bf16 <-> fp32: a bf16 is the top 16 bits of an fp32, so widening is a shift. Two bf16 values are read
// as one uint (little-endian: element 2i in the low half).
float bf16_lo(uint packed) { return uintBitsToFloat(packed << 16); }
float bf16_hi(uint packed) { return uintBitsToFloat(packed & 0xffff0000u); }
// Round-to-nearest-even narrowing (NaN kept NaN).
uint f32_to_bf16_bits(float f) {
  uint u = floatBitsToUint(f);
  if ((u & 0x7fffffffu) > 0x7f800000u) return (u >> 16) | 0x40u;
  return (u + 0x7fffu + ((u >> 16) & 1u)) >> 16;
}
