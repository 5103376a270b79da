// Philox4x32-10 (Salmon et al. 2011), bit-identical to engine/src/tensor/philox.hpp, which documents the
// stream layout: key = seed (lo, hi); counter = (block lo, block hi, stream, retry); element e uses word
// e % 4 of block e / 4.
uvec4 philox4x32_10(uvec4 c, uvec2 k) {
  for (int round = 0; round < 10; ++round) {
    uint hi0, lo0, hi1, lo1;
    umulExtended(0xD2511F53u, c.x, hi0, lo0);
    umulExtended(0xCD9E8D57u, c.z, hi1, lo1);
    c = uvec4(hi1 ^ c.y ^ k.x, lo1, hi0 ^ c.w ^ k.y, lo0);
    k += uvec2(0x9E3779B9u, 0xBB67AE85u);
  }
  return c;
}

// Top 24 bits times 2^-24: [0, 1 - 2^-24], exact in fp32.
float philox_uniform(uint x) { return float(x >> 8) * (1.0 / 16777216.0); }

// Deterministic log / sqrt / cos / sin for Box–Muller: the same +, -, × steps in the same order as
// philox::detail in philox.hpp, every one `precise` (never fused or reordered). Those operations are
// correctly rounded on every conformant Vulkan device, so normals match the host bit for bit everywhere.
float philox_recip(float d) {
  precise float y = uintBitsToFloat(0x7EF311C7u - floatBitsToUint(d));
  for (int i = 0; i < 4; ++i) {
    precise float dy = d * y;
    precise float corr = 2.0 - dy;
    y = y * corr;
  }
  return y;
}

float philox_log(float x) {
  uint b = floatBitsToUint(x);
  int e = int(b >> 23) - 127;
  precise float m = uintBitsToFloat((b & 0x7fffffu) | 0x3f800000u);
  if (m > uintBitsToFloat(0x3fb504f3u)) {
    m = m * 0.5;
    e += 1;
  }
  precise float f = m - 1.0;
  precise float den = 2.0 + f;
  precise float s = f * philox_recip(den);
  precise float s2 = s * s;
  precise float p = uintBitsToFloat(0x3de38e39u);
  p = uintBitsToFloat(0x3e124925u) + s2 * p;
  p = uintBitsToFloat(0x3e4ccccdu) + s2 * p;
  p = uintBitsToFloat(0x3eaaaaabu) + s2 * p;
  precise float s3 = s * s2;
  precise float series = s + s3 * p;
  precise float ef = float(e);
  precise float tail = ef * uintBitsToFloat(0x35bfbe8eu) + 2.0 * series;
  precise float result = ef * uintBitsToFloat(0x3f317200u) + tail;
  return result;
}

vec2 philox_cossin_2pi(float v) {
  precise float q = v * 4.0;
  int k = int(q);
  precise float r = q - float(k);
  if (r >= 0.5) {
    r = r - 1.0;
    k += 1;
  }
  precise float x = r * uintBitsToFloat(0x3fc90fdbu);
  precise float x2 = x * x;
  precise float ps = uintBitsToFloat(0x3638ef1du);
  ps = uintBitsToFloat(0xb9500d01u) + x2 * ps;
  ps = uintBitsToFloat(0x3c088889u) + x2 * ps;
  ps = uintBitsToFloat(0xbe2aaaabu) + x2 * ps;
  precise float x3 = x * x2;
  precise float sn = x + x3 * ps;
  precise float pc = uintBitsToFloat(0x37d00d01u);
  pc = uintBitsToFloat(0xbab60b61u) + x2 * pc;
  pc = uintBitsToFloat(0x3d2aaaabu) + x2 * pc;
  pc = -0.5 + x2 * pc;
  precise float cs = 1.0 + x2 * pc;
  switch (k & 3) {
    case 0: return vec2(cs, sn);
    case 1: return vec2(-sn, cs);
    case 2: return vec2(-cs, -sn);
    default: return vec2(sn, -cs);
  }
}

float philox_sqrt(float t) {
  if (!(t > 0.0)) return 0.0;
  precise float half_t = 0.5 * t;
  precise float y = uintBitsToFloat(0x5f3759dfu - (floatBitsToUint(t) >> 1));
  for (int i = 0; i < 4; ++i) {
    precise float hy = half_t * y;
    precise float hyy = hy * y;
    precise float corr = 1.5 - hyy;
    y = y * corr;
  }
  precise float result = t * y;
  return result;
}

// Box–Muller on (even, odd) words: r = sqrt(-2 ln(1 - u)), θ = 2π v; returns (r cos θ, r sin θ).
vec2 philox_box_muller(uint even, uint odd) {
  float u = philox_uniform(even), v = philox_uniform(odd);
  precise float w = 1.0 - u;
  precise float t = -2.0 * philox_log(w);
  float r = philox_sqrt(t);
  vec2 cs = philox_cossin_2pi(v);
  precise vec2 result = r * cs;
  return result;
}
