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
#include <bit>
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

// Deterministic float math for Box–Muller. Only +, -, × and exact conversions are used, each correctly
// rounded in IEEE-754 and in Vulkan (SPIR-V OpFAdd/OpFSub/OpFMul), in a fixed order and never fused (the
// shader marks every step `precise`; C++ contracts nothing under -std=c++20, and x86-64 SSE evaluates in
// float). So the shader's normals equal these bit for bit on every conformant device, which the device's
// log/sin/cos/sqrt (a few ulp, implementation-defined) would not give. No step meets a subnormal.
namespace detail {
inline float f32(uint32_t bits) { return std::bit_cast<float>(bits); }

// 1/d for d in [1, 4): bit-trick guess, then 4 Newton steps y·(2 - d·y).
inline float recip(float d) {
  float y = f32(0x7EF311C7u - std::bit_cast<uint32_t>(d));
  for (int i = 0; i < 4; ++i) {
    const float dy = d * y;
    const float corr = 2.0f - dy;
    y = y * corr;
  }
  return y;
}

// ln x for a positive normal x: x = m·2^e with m in [√½, √2); ln m = 2·atanh(s), s = (m - 1)/(m + 1),
// odd series to s^9 (|s| ≤ 0.172: truncation < 4e-10); ln 2 split in a 16-bit head and a tail.
inline float log(float x) {
  const uint32_t b = std::bit_cast<uint32_t>(x);
  int e = int(b >> 23) - 127;
  float m = f32((b & 0x7fffffu) | 0x3f800000u);
  if (m > f32(0x3fb504f3u)) {  // √2
    m = m * 0.5f;
    e += 1;
  }
  const float f = m - 1.0f;
  const float den = 2.0f + f;
  const float s = f * recip(den);
  const float s2 = s * s;
  float p = f32(0x3de38e39u);           // 1/9
  p = f32(0x3e124925u) + s2 * p;        // 1/7
  p = f32(0x3e4ccccdu) + s2 * p;        // 1/5
  p = f32(0x3eaaaaabu) + s2 * p;        // 1/3
  const float s3 = s * s2;
  const float series = s + s3 * p;
  const float ef = float(e);
  const float tail = ef * f32(0x35bfbe8eu) + 2.0f * series;  // ln2_lo
  return ef * f32(0x3f317200u) + tail;                          // ln2_hi
}

// (cos 2πv, sin 2πv) for v in [0, 1) with at most 24 significant bits: exact quadrant reduction, then
// Taylor polynomials on |x| ≤ π/4 (truncation < 3e-8).
inline void sincos_2pi(float v, float& c, float& s) {
  const float q = v * 4.0f;
  int k = int(q);
  float r = q - float(k);
  if (r >= 0.5f) {
    r = r - 1.0f;
    k += 1;
  }
  const float x = r * f32(0x3fc90fdbu);  // π/2
  const float x2 = x * x;
  float ps = f32(0x3638ef1du);           // 1/9!
  ps = f32(0xb9500d01u) + x2 * ps;       // -1/7!
  ps = f32(0x3c088889u) + x2 * ps;       // 1/5!
  ps = f32(0xbe2aaaabu) + x2 * ps;       // -1/3!
  const float x3 = x * x2;
  const float sn = x + x3 * ps;
  float pc = f32(0x37d00d01u);           // 1/8!
  pc = f32(0xbab60b61u) + x2 * pc;       // -1/6!
  pc = f32(0x3d2aaaabu) + x2 * pc;       // 1/4!
  pc = -0.5f + x2 * pc;
  const float cs = 1.0f + x2 * pc;
  switch (k & 3) {
    case 0: c = cs; s = sn; break;
    case 1: c = -sn; s = cs; break;
    case 2: c = -cs; s = -sn; break;
    default: c = sn; s = -cs; break;
  }
}

// √t for t ≥ 0: inverse square root by the bit trick and 4 Newton steps y·(1.5 - ½t·y·y), times t.
inline float sqrt(float t) {
  if (!(t > 0.0f)) return 0.0f;
  const float half_t = 0.5f * t;
  float y = f32(0x5f3759dfu - (std::bit_cast<uint32_t>(t) >> 1));
  for (int i = 0; i < 4; ++i) {
    const float hy = half_t * y;
    const float hyy = hy * y;
    const float corr = 1.5f - hyy;
    y = y * corr;
  }
  return t * y;
}
}  // namespace detail

// Box–Muller on the word pairs (w0, w1) and (w2, w3) of a block: with u = uniform(w_even), v = uniform(w_odd),
// r = sqrt(-2 ln(1 - u)) (1 - u is in [2^-24, 1], so the log is finite) and θ = 2π v,
// the element of word w_even gets r·cos θ and the element of word w_odd gets r·sin θ.
// log, sqrt, cos and sin are the deterministic ones above (accurate to ~1e-7 relative): the shader's values
// equal these bit for bit.
inline float normal_from_pair(uint32_t even, uint32_t odd, bool want_odd) {
  const float u = uniform_from_bits(even), v = uniform_from_bits(odd);
  const float w = 1.0f - u;
  const float t = -2.0f * detail::log(w);
  const float r = detail::sqrt(t);
  float c, s;
  detail::sincos_2pi(v, c, s);
  return want_odd ? r * s : r * c;
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
