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

// Box–Muller on (even, odd) words: r = sqrt(-2 ln(1 - u)), θ = 2π v; returns (r cos θ, r sin θ).
vec2 philox_box_muller(uint even, uint odd) {
  float u = philox_uniform(even), v = philox_uniform(odd);
  float r = sqrt(-2.0 * log(1.0 - u));
  float theta = 6.2831853071795864769 * v;
  return r * vec2(cos(theta), sin(theta));
}
