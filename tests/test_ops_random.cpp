// Philox4x32-10: the host implementation against the Random123 known-answer vectors, the shader against the
// host bit for bit (uniforms, integers; normals to the device's transcendental precision), and the
// distributions' statistics.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <iostream>
#include <functional>
#include <vector>

#include "support/gpu.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_random.hpp"
#include "tensor/philox.hpp"

namespace dvs {
namespace {

class RandomOps : public test::GpuTest {};

TEST(Philox, KnownAnswerVectors) {
  // Random123 kat_vectors, philox4x32_10.
  auto check = [](philox::Block c, uint32_t k0, uint32_t k1, philox::Block want) {
    philox::Block got = philox::philox4x32_10(c, k0, k1);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(got.w[i], want.w[i]) << "word " << i;
  };
  check({{0, 0, 0, 0}}, 0, 0, {{0x6627e8d5u, 0xe169c58du, 0xbc57ac4cu, 0x9b00dbd8u}});
  check({{0xffffffffu, 0xffffffffu, 0xffffffffu, 0xffffffffu}}, 0xffffffffu, 0xffffffffu,
        {{0x408f276du, 0x41c83b0eu, 0xa20bc7c6u, 0x6d5451fdu}});
  check({{0x243f6a88u, 0x85a308d3u, 0x13198a2eu, 0x03707344u}}, 0xa4093822u, 0x299f31d0u,
        {{0xd16cfe09u, 0x94fdccebu, 0x5001e420u, 0x24126ea1u}});
}

TEST(Philox, LemireIsUnbiasedOnSmallWordSpace) {
  // The threshold rule accepts exactly floor(2^32 / n) words per result; check the counting argument on a
  // scaled-down model (8-bit words) where every word can be enumerated.
  for (uint32_t n : {3u, 7u, 100u, 255u}) {
    const uint32_t threshold = (256u - n) % n;
    std::vector<int> hits(n, 0);
    for (uint32_t x = 0; x < 256; ++x) {
      uint32_t m = x * n;
      if ((m & 0xffu) >= threshold) hits[m >> 8]++;
    }
    for (uint32_t r = 0; r < n; ++r) EXPECT_EQ(hits[r], int(256 / n)) << "n=" << n << " r=" << r;
  }
}

std::vector<float> gpu_floats(vk::Context& ctx, int64_t n, const std::function<void(vk::Recorder&, const Tensor&)>& f) {
  Tensor t = Tensor::empty(ctx, {n}, DType::f32);
  ops::run_now(ctx, [&](vk::Recorder& r) { f(r, t); });
  return t.download(ctx).to_f32();
}

TEST_F(RandomOps, PhiloxUniformMatchesHostBitForBit) {
  for (auto [n, base] : std::vector<std::pair<int64_t, uint64_t>>{{1, 0}, {7, 0}, {33, 5}, {129, 3}, {1001, (1ull << 34) + 2}}) {
    ops::RandomStream s{0x0123456789abcdefull, 7, base};
    auto got = gpu_floats(ctx(), n, [&](vk::Recorder& r, const Tensor& t) { ops::random_uniform(r, t, s); });
    for (int64_t i = 0; i < n; ++i) {
      float want = philox::uniform(s.seed, s.stream, base + uint64_t(i));
      ASSERT_EQ(std::bit_cast<uint32_t>(got[size_t(i)]), std::bit_cast<uint32_t>(want)) << "n=" << n << " i=" << i;
      ASSERT_GE(got[size_t(i)], 0.0f);
      ASSERT_LT(got[size_t(i)], 1.0f);
    }
  }
  // A slice regenerated alone equals the same elements of the whole draw.
  ops::RandomStream whole{42, 0, 0}, part{42, 0, 13};
  auto a = gpu_floats(ctx(), 64, [&](vk::Recorder& r, const Tensor& t) { ops::random_uniform(r, t, whole); });
  auto b = gpu_floats(ctx(), 20, [&](vk::Recorder& r, const Tensor& t) { ops::random_uniform(r, t, part); });
  for (int i = 0; i < 20; ++i) EXPECT_EQ(a[size_t(13 + i)], b[size_t(i)]);
  // Another stream or seed gives other numbers.
  ops::RandomStream other{42, 1, 0};
  auto c = gpu_floats(ctx(), 64, [&](vk::Recorder& r, const Tensor& t) { ops::random_uniform(r, t, other); });
  int same = 0;
  for (int i = 0; i < 64; ++i) same += a[size_t(i)] == c[size_t(i)];
  EXPECT_LT(same, 3);
}

TEST_F(RandomOps, PhiloxNormalMatchesHostAndStatistics) {
  const int64_t n = 1 << 18;
  ops::RandomStream s{20241121, 3, 1};
  auto got = gpu_floats(ctx(), n, [&](vk::Recorder& r, const Tensor& t) { ops::random_normal(r, t, s); });
  // Bit for bit: Box-Muller uses only correctly rounded +, -, x in a fixed order on both sides.
  double sum = 0, sum2 = 0, max_diff = 0;
  for (int64_t i = 0; i < n; ++i) {
    float x = got[size_t(i)];
    ASSERT_TRUE(std::isfinite(x)) << i;
    float want = philox::normal(s.seed, s.stream, s.base + uint64_t(i));
    ASSERT_EQ(std::bit_cast<uint32_t>(x), std::bit_cast<uint32_t>(want)) << "element " << i;
    sum += x;
    sum2 += double(x) * x;
  }
  // The deterministic log/sqrt/cos/sin agree with libm's double-precision Box-Muller to ~1e-6.
  for (int64_t i = 0; i < 4096; ++i) {
    const philox::Block b = philox::raw_block(s.seed, s.stream, (s.base + uint64_t(i)) / 4);
    const unsigned w = unsigned((s.base + uint64_t(i)) % 4), pair = w & 2u;
    const double u = philox::uniform_from_bits(b.w[pair]), v = philox::uniform_from_bits(b.w[pair + 1]);
    const double r = std::sqrt(-2.0 * std::log(1.0 - u)), th = 2.0 * M_PI * v;
    const double exact = (w & 1u) ? r * std::sin(th) : r * std::cos(th);
    max_diff = std::max(max_diff, std::fabs(double(got[size_t(i)]) - exact) / (1.0 + std::fabs(exact)));
  }
  EXPECT_LT(max_diff, 2e-6);
  std::cout << "normal vs double-precision Box-Muller: max |d|/(1+|x|) = " << max_diff << "\n";
  double mean = sum / n, var = sum2 / n - mean * mean;
  // 5-sigma bounds: sd(mean) = 1/sqrt(n), sd(var) = sqrt(2/n).
  EXPECT_LT(std::fabs(mean), 5.0 / std::sqrt(double(n)));
  EXPECT_LT(std::fabs(var - 1.0), 5.0 * std::sqrt(2.0 / n));
  // The mean/std parameters are applied as mean + std * z.
  auto shifted = gpu_floats(ctx(), 9, [&](vk::Recorder& r, const Tensor& t) { ops::random_normal(r, t, s, 2.0f, 0.5f); });
  for (int i = 0; i < 9; ++i) EXPECT_EQ(shifted[size_t(i)], 2.0f + 0.5f * got[size_t(i)]);
}

std::vector<int32_t> gpu_ints(vk::Context& ctx, int64_t n, const ops::RandomStream& s, uint32_t range) {
  Tensor t = Tensor::empty(ctx, {n}, DType::i32);
  ops::run_now(ctx, [&](vk::Recorder& r) { ops::random_below(r, t, s, range); });
  HostTensor h = t.download(ctx);
  return std::vector<int32_t>(h.as<int32_t>(), h.as<int32_t>() + n);
}

TEST_F(RandomOps, PhiloxIntegersExactInRangeAndUniform) {
  // Exact equality with the host, including a range where ~25% of draws are rejected and retried.
  for (uint32_t range : {1u, 10u, 1000003u, (1u << 30) + 1u}) {
    ops::RandomStream s{99, 11, 2};
    auto got = gpu_ints(ctx(), 4099, s, range);
    for (int64_t i = 0; i < 4099; ++i) {
      ASSERT_EQ(uint32_t(got[size_t(i)]), philox::below(s.seed, s.stream, s.base + uint64_t(i), range))
          << "range=" << range << " i=" << i;
      ASSERT_GE(got[size_t(i)], 0);
      ASSERT_LT(uint32_t(got[size_t(i)]), range);
    }
  }
  // Chi-square over 37 buckets, 200k draws: 36 degrees of freedom, P(chi2 > 80) < 1e-4.
  const uint32_t k = 37;
  const int64_t n = 200000;
  auto got = gpu_ints(ctx(), n, {7, 0, 0}, k);
  std::vector<double> count(k, 0);
  for (int32_t v : got) count[size_t(v)]++;
  double expect = double(n) / k, chi2 = 0;
  for (double c : count) chi2 += (c - expect) * (c - expect) / expect;
  EXPECT_LT(chi2, 80.0);
}

TEST_F(RandomOps, PhiloxEmptyTensorIsANoOp) {
  Tensor t = Tensor::empty(ctx(), {0}, DType::f32);
  ops::run_now(ctx(), [&](vk::Recorder& r) { ops::random_normal(r, t, {1, 0, 0}); });
  Tensor ints = Tensor::empty(ctx(), {4}, DType::i32);
  EXPECT_THROW(ops::run_now(ctx(), [&](vk::Recorder& r) { ops::random_below(r, ints, {1, 0, 0}, 0); }), Error);
  EXPECT_THROW(ops::run_now(ctx(), [&](vk::Recorder& r) { ops::random_below(r, t, {1, 0, 0}, 5); }), Error);
}

}  // namespace
}  // namespace dvs
