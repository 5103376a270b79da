// Reductions over x larger than one binding: the partials pass reads x through windows of whole blocks (and
// blocks shrink where a binding cannot hold one), merged by the same second level. Under binding=1KiB every
// case below splits; results agree with the call under the limits in force before within the reductions'
// tolerance (the block partition may differ), max exactly, with more dispatches.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <optional>
#include <random>
#include <vector>

#include "support/gpu.hpp"
#include "support/split_check.hpp"
#include "tensor/ops_reduce.hpp"

namespace dvs {
namespace {

class SplitReduce : public test::GpuTest {};

Tensor random_tensor(vk::Context& ctx, const Shape& s, uint32_t seed, float offset) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> d(0.0f, 1.0f);
  std::vector<float> v(size_t(shape_numel(s)));
  for (float& x : v) x = offset + d(rng);
  return Tensor::upload(ctx, HostTensor::from_f32(s, v));
}

// Runs `op` under the limits in force and under binding=1KiB (scratch sized for each); returns the outputs
// of both and checks that the second split more.
std::pair<std::vector<float>, std::vector<float>> both(
    vk::Context& ctx, const ops::Segments& segs, int64_t outs,
    const std::function<void(vk::Recorder&, const Tensor&, const Tensor&, const Tensor&)>& op) {
  std::vector<float> r[2];
  uint32_t d[2];
  for (int i = 0; i < 2; ++i) {
    std::optional<test::ScopedLimits> limits;
    if (i == 1) limits.emplace(ctx, "binding=1KiB,groups=64");
    const Tensor o0 = Tensor::zeros(ctx, {outs}, DType::f32), o1 = Tensor::zeros(ctx, {outs}, DType::f32);
    const Tensor scratch = Tensor::zeros(ctx, {ops::reduce_scratch_elems(ctx.caps(), segs)}, DType::f32);
    d[i] = test::run_counted(ctx, [&](vk::Recorder& rec) { op(rec, o0, o1, scratch); });
    r[i] = o0.download(ctx).to_f32();
    const std::vector<float> v1 = o1.download(ctx).to_f32();
    r[i].insert(r[i].end(), v1.begin(), v1.end());
  }
  EXPECT_GT(d[1], d[0]) << "did not split";
  return {r[0], r[1]};
}

TEST_F(SplitReduce, SumAndMaxOverWindows) {
  for (const int64_t n : {5003, 4096 + 1024}) {
    const Tensor x = random_tensor(ctx(), {n}, 1, 0.25f);
    const auto [a, b] = both(ctx(), ops::Segments{1, n, n, 0, 0}, 1,
                             [&](vk::Recorder& r, const Tensor& s, const Tensor& m, const Tensor& scratch) {
                               ops::sum_all(r, x, s, scratch);
                               ops::max_all(r, x, m, scratch);
                             });
    EXPECT_NEAR(a[0], b[0], 1e-6 * double(n) * 2) << "sum n=" << n;
    EXPECT_EQ(a[1], b[1]) << "max n=" << n;
  }
}

TEST_F(SplitReduce, ChannelMeanVarOverStridedWindows) {
  // [outer, C, inner] with odd sizes: each channel's elements are runs of `inner` strided by C·inner (within
  // one binding, so blocks may span several runs; wider strides need one-run blocks and far more scratch).
  for (const Shape& s : std::vector<Shape>{{41, 3, 23}, {97, 2, 13}, {31, 5, 7}}) {
    const Tensor x = random_tensor(ctx(), s, 2, 100.0f);
    const auto [a, b] = both(ctx(), ops::channel_segments(s[0], s[1], s[2]), s[1],
                             [&](vk::Recorder& r, const Tensor& mean, const Tensor& var, const Tensor& scratch) {
                               ops::channel_mean_var(r, x, s[0], s[1], s[2], mean, var, scratch);
                             });
    // Both against the double-precision statistics (mean: a few fp32 ulps of the offset; variance as in
    // test_ops_reduce).
    const std::vector<float> h = x.download(ctx()).to_f32();
    for (int64_t c = 0; c < s[1]; ++c) {
      double mean = 0, var = 0;
      const int64_t n = s[0] * s[2];
      for (int64_t o = 0; o < s[0]; ++o)
        for (int64_t i = 0; i < s[2]; ++i) mean += h[size_t((o * s[1] + c) * s[2] + i)];
      mean /= double(n);
      for (int64_t o = 0; o < s[0]; ++o)
        for (int64_t i = 0; i < s[2]; ++i) var += std::pow(h[size_t((o * s[1] + c) * s[2] + i)] - mean, 2);
      var /= double(n);
      const std::string at = " c=" + std::to_string(c) + " [" + shape_str(s) + "]";
      for (const auto* r : {&a, &b}) {
        EXPECT_NEAR((*r)[size_t(c)], mean, 4e-6 * (100.0 + double(s[1]) + 1.0)) << "mean" << at;
        EXPECT_NEAR((*r)[size_t(s[1] + c)], var, 2e-5 * var + 1e-12) << "var" << at;
      }
    }
  }
}

}  // namespace
}  // namespace dvs
