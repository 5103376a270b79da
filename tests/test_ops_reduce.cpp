// Reductions: per-channel mean / population variance (AdaIN statistics), whole-tensor sum and max, against
// C++ references in double; sizes that span one and many blocks, and large offsets that would cancel in a
// one-pass sum of squares.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "support/gpu.hpp"
#include "tensor/ops_reduce.hpp"

namespace dvs {
namespace {

using test::GpuTest;
using ReduceOps = GpuTest;  // the suite name selects these for the DVS_TUNING=gpu pass

std::vector<float> random_values(size_t n, uint32_t seed, float offset, float spread) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> dist(0.0f, 1.0f);
  std::vector<float> v(n);
  for (float& x : v) x = offset + spread * dist(rng);
  return v;
}

// Sized for the limits in force (blocks shrink under tiny bindings).
Tensor scratch_for(vk::Context& ctx, const ops::Segments& segs) {
  return Tensor::empty(ctx, {ops::reduce_scratch_elems(ctx.caps(), segs)}, DType::f32, "reduce scratch");
}

// Tolerance: mean within 1e-6*(|offset| + spread) absolute; variance within 2e-5 relative.
void run_channel_stats(vk::Context& ctx, int64_t outer, int64_t C, int64_t inner, float offset, float spread) {
  std::vector<float> x = random_values(size_t(outer * C * inner), 61 + uint32_t(C), offset, spread);
  // Give each channel its own offset so a channel mix-up shows.
  for (int64_t o = 0; o < outer; ++o)
    for (int64_t c = 0; c < C; ++c)
      for (int64_t i = 0; i < inner; ++i) x[size_t((o * C + c) * inner + i)] += float(c);
  std::vector<double> mean(size_t(C), 0.0), var(size_t(C), 0.0);
  const double n = double(outer * inner);
  for (int64_t c = 0; c < C; ++c) {
    for (int64_t o = 0; o < outer; ++o)
      for (int64_t i = 0; i < inner; ++i) mean[size_t(c)] += x[size_t((o * C + c) * inner + i)];
    mean[size_t(c)] /= n;
    for (int64_t o = 0; o < outer; ++o)
      for (int64_t i = 0; i < inner; ++i) {
        double d = x[size_t((o * C + c) * inner + i)] - mean[size_t(c)];
        var[size_t(c)] += d * d;
      }
    var[size_t(c)] /= n;
  }
  Tensor xt = Tensor::upload(ctx, HostTensor::from_f32({outer, C, inner}, x));
  Tensor mt = Tensor::empty(ctx, {C}, DType::f32), vt = Tensor::empty(ctx, {C}, DType::f32);
  Tensor scratch = scratch_for(ctx, ops::channel_segments(outer, C, inner));
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::channel_mean_var(rec, xt, outer, C, inner, mt, vt, scratch); });
  std::vector<float> gm = mt.download(ctx).to_f32(), gv = vt.download(ctx).to_f32();
  const std::string what = "channel_mean_var [" + std::to_string(outer) + ", " + std::to_string(C) + ", " +
                           std::to_string(inner) + "] offset " + std::to_string(offset);
  for (int64_t c = 0; c < C; ++c) {
    EXPECT_NEAR(gm[size_t(c)], mean[size_t(c)], 1e-6 * (std::abs(offset) + float(C) + spread)) << what << " c=" << c;
    EXPECT_NEAR(gv[size_t(c)], var[size_t(c)], 2e-5 * var[size_t(c)] + 1e-12) << what << " c=" << c;
  }
}

TEST_F(ReduceOps, ChannelMeanVarOddShapes) {
  run_channel_stats(ctx(), 1, 1, 1, 0.0f, 1.0f);   // one element: variance 0
  run_channel_stats(ctx(), 7, 3, 33, 0.5f, 2.0f);
  run_channel_stats(ctx(), 3, 5, 1, 0.0f, 1.0f);   // [N, C] layout (inner = 1)
  run_channel_stats(ctx(), 13, 4, 129, -3.0f, 1.0f);  // tiny latent-like [F, C, H*W]
}

TEST_F(ReduceOps, ChannelMeanVarManyBlocksLargeOffset) {
  // Latent-sized channel: 13 frames x 60x90 = 70,200 elements per channel (18 blocks), offset 1000, std 0.5: a
  // one-pass E[x^2] - E[x]^2 in fp32 would lose the variance entirely.
  run_channel_stats(ctx(), 13, 3, 60 * 90, 1000.0f, 0.5f);
}

// Tolerance: sum within 1e-6 * sum|x| (+1e-6); max exact.
void run_sum_max(vk::Context& ctx, int64_t n, float offset) {
  std::vector<float> x = random_values(size_t(n), 71 + uint32_t(n % 1000), offset, 1.0f);
  double sum = 0, abs_sum = 0;
  for (float v : x) {
    sum += v;
    abs_sum += std::abs(v);
  }
  const float mx = *std::max_element(x.begin(), x.end());
  Tensor xt = Tensor::upload(ctx, HostTensor::from_f32({n}, x));
  Tensor st = Tensor::empty(ctx, {1}, DType::f32), mt = Tensor::empty(ctx, {1}, DType::f32);
  Tensor scratch = scratch_for(ctx, ops::Segments{1, n, n, 0, 0});
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    ops::sum_all(rec, xt, st, scratch);
    ops::max_all(rec, xt, mt, scratch);
  });
  EXPECT_NEAR(st.download(ctx).to_f32()[0], sum, 1e-6 * abs_sum + 1e-6) << "sum n=" << n;
  EXPECT_EQ(mt.download(ctx).to_f32()[0], mx) << "max n=" << n;
}

TEST_F(ReduceOps, SumAndMax) {
  for (int64_t n : {1, 7, 33, 4096, 4097}) run_sum_max(ctx(), n, 0.0f);
  run_sum_max(ctx(), 1 << 20, 3.0f);  // 256 blocks; all-positive sum of ~3e6
  run_sum_max(ctx(), 1000, -50.0f);   // all negative: max must not be 0
}

TEST_F(ReduceOps, ReduceRejectsSmallScratch) {
  Tensor x = Tensor::zeros(ctx(), {10000}, DType::f32), out = Tensor::zeros(ctx(), {1}, DType::f32);
  Tensor scratch = Tensor::zeros(ctx(), {2}, DType::f32);  // needs 10 partials x 2
  vk::Recorder rec(ctx());
  rec.begin();
  EXPECT_THROW(ops::sum_all(rec, x, out, scratch), Error);
}

}  // namespace
}  // namespace dvs
