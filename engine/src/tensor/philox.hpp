// Philox4x32-10 on the host (Salmon, Moraes, Dror, Shaw, "Parallel random numbers: as easy as 1, 2, 3",
// SC 2011): the reference that shaders/common/philox.glsl must match bit for bit, and the definition of
// how dvs turns (seed, element index) into numbers. Header-only; no state besides the arguments.
//
// Stream layout (shared with the shaders):
//   key     = (seed & 0xffffffff, seed >> 32)
//   counter = (block & 0xffffffff, block >> 32, stream, retry)
// Element e of a draw uses block = e / 4 and word e % 4 of that block, so each element's value depends only
// on (seed, stream, e): never on tensor shape, thread mapping or device. `stream` separates independent
// draws under one seed; `retry` is 0 except for the rejection loop of uniform integers.
#pragma once
#include <cmath>
#include <cstdint>

namespace dvs::philox {

struct Block {
  uint32_t w[4];
};

constexpr uint32_t kMul0 = 0xD2511F53u, kMul1 = 0xCD9E8D57u;
constexpr uint32_t kWeyl0 = 0x9E3779B9u, kWeyl1 = 0xBB67AE85u;

// Ten rounds of Philox4x32: S-box = two 32x32->64 multiplies, key bumped by the Weyl constants between rounds.
inline Block philox4x32_10(Block c, uint32_t k0, uint32_t k1) {
  for (int round = 0; round < 10; ++round) {
    const uint64_t p0 = uint64_t(kMul0) * c.w[0], p1 = uint64_t(kMul1) * c.w[2];
    const uint32_t hi0 = uint32_t(p0 >> 32), lo0 = uint32_t(p0);
    const uint32_t hi1 = uint32_t(p1 >> 32), lo1 = uint32_t(p1);
    c = Block{{hi1 ^ c.w[1] ^ k0, lo1, hi0 ^ c.w[3] ^ k1, lo0}};
    k0 += kWeyl0;
    k1 += kWeyl1;
  }
  return c;
}

// The four raw words for a given block of a draw.
inline Block raw_block(uint64_t seed, uint32_t stream, uint64_t block, uint32_t retry = 0) {
  return philox4x32_10(Block{{uint32_t(block), uint32_t(block >> 32), stream, retry}}, uint32_t(seed),
                       uint32_t(seed >> 32));
}

inline uint32_t raw_word(uint64_t seed, uint32_t stream, uint64_t element, uint32_t retry = 0) {
  return raw_block(seed, stream, element / 4, retry).w[element % 4];
}

// Uniform in [0, 1): the top 24 bits of the word times 2^-24 (exact in fp32; largest value 1 - 2^-24).
inline float uniform_from_bits(uint32_t x) { return float(x >> 8) * 0x1p-24f; }

inline float uniform(uint64_t seed, uint32_t stream, uint64_t element) {
  return uniform_from_bits(raw_word(seed, stream, element));
}

// Box–Muller on the word pairs (w0, w1) and (w2, w3) of a block: with u = uniform(w_even), v = uniform(w_odd),
// r = sqrt(-2 ln(1 - u)) (1 - u is in [2^-24, 1], so the log is finite) and θ = 2π v,
// element of word w_even gets r·cos θ and element of word w_odd gets r·sin θ.
// The shaders use the device's log/sqrt/cos/sin, whose last bits may differ from libm's: normals agree with
// this reference to ~1e-6 relative (bit-identical on the same device), uniforms and integers bit for bit.
inline float normal_from_pair(uint32_t even, uint32_t odd, bool want_odd) {
  const float u = uniform_from_bits(even), v = uniform_from_bits(odd);
  const float r = std::sqrt(-2.0f * std::log(1.0f - u));
  const float theta = 6.2831853071795864769f * v;
  return want_odd ? r * std::sin(theta) : r * std::cos(theta);
}

inline float normal(uint64_t seed, uint32_t stream, uint64_t element) {
  const Block b = raw_block(seed, stream, element / 4);
  const unsigned pair = unsigned(element % 4) & 2u;
  return normal_from_pair(b.w[pair], b.w[pair + 1], element & 1u);
}

// Unbiased integer in [0, n), n ≥ 1 (Lemire's multiply-shift with rejection): m = x·n (64-bit); reject when
// the low half of m is below 2^32 mod n, which leaves every result with exactly floor(2^32 / n) accepted
// words. A rejected draw moves to the same word of the block at counter retry + 1, so the value still depends
// only on (seed, stream, element). After kMaxRetries rejections (probability < (n / 2^32)^64) the last
// draw is accepted.
constexpr uint32_t kMaxRetries = 64;

inline uint32_t below(uint64_t seed, uint32_t stream, uint64_t element, uint32_t n) {
  const uint32_t threshold = uint32_t(0u - n) % n;  // 2^32 mod n
  uint64_t m = 0;
  for (uint32_t retry = 0; retry <= kMaxRetries; ++retry) {
    m = uint64_t(raw_word(seed, stream, element, retry)) * n;
    if (uint32_t(m) >= threshold) break;
  }
  return uint32_t(m >> 32);
}

}  // namespace dvs::philox
