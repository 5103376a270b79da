// Loaders of a norm's affine weight and bias [n] from packed storage (f32, bf16 or f16, declared as uvec4
// arrays): NAME1(i) is element i, NAME4(j) elements 4j..4j+3. The includer declares WDTYPE (0 f32, 1 bf16,
// 2 f16) and the arrays, then instantiates WEIGHT_LOADERS(load_w, w4) for each.
float half_bits_to_float(uint h) { return WDTYPE == 1 ? uintBitsToFloat(h << 16) : unpackHalf2x16(h).x; }
#define WEIGHT_LOADERS(NAME, ARR)                                                              \
  float NAME##1(uint i) {                                                                      \
    if (WDTYPE == 0) return uintBitsToFloat(ARR[i >> 2][i & 3u]);                             \
    uint word = ARR[i >> 3][(i >> 1) & 3u];                                                    \
    return half_bits_to_float((i & 1u) != 0u ? word >> 16 : word & 0xffffu);                   \
  }                                                                                            \
  vec4 NAME##4(uint j) {                                                                       \
    if (WDTYPE == 0) return uintBitsToFloat(ARR[j]);                                           \
    uvec4 q = ARR[j >> 1];                                                                     \
    uvec2 wd = (j & 1u) == 0u ? q.xy : q.zw;                                                   \
    if (WDTYPE == 1)                                                                           \
      return vec4(uintBitsToFloat(wd.x << 16), uintBitsToFloat(wd.x & 0xffff0000u),            \
                  uintBitsToFloat(wd.y << 16), uintBitsToFloat(wd.y & 0xffff0000u));           \
    return vec4(unpackHalf2x16(wd.x), unpackHalf2x16(wd.y));                                   \
  }
