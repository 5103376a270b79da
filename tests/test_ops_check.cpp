// The device-side NaN/Inf scan (ops::NonFiniteCheck, shaders/nn/nonfinite.comp) against a plain C++ count
// and first index: clean tensors, planted NaN/+Inf/-Inf at the start, the end, an odd tail and across the
// ranges of a split scan; several tensors in one recording keep their own slots; texel and storage reads.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "dvs/error.hpp"
#include "support/gpu.hpp"
#include "support/texel_paths.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_check.hpp"
#include "tensor/ops_elementwise.hpp"

namespace dvs {
namespace {

using test::GpuTest;

std::vector<float> random_values(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> dist(0.0f, 1e3f);  // large finite values, incl. near-max exponents below
  std::vector<float> v(n);
  for (float& x : v) x = dist(rng);
  if (n > 2) v[1] = std::numeric_limits<float>::max(), v[2] = -std::numeric_limits<float>::denorm_min();
  return v;
}

struct Reference {
  uint64_t count = 0;
  int64_t first = -1;
};
Reference reference(const std::vector<float>& v) {
  Reference r;
  for (size_t i = 0; i < v.size(); ++i)
    if (!std::isfinite(v[i])) {
      if (r.first < 0) r.first = int64_t(i);
      ++r.count;
    }
  return r;
}

std::vector<ops::NonFiniteHit> scan(vk::Context& ctx, const std::vector<std::vector<float>>& tensors, VkDeviceSize range = 0) {
  ops::NonFiniteCheck check(ctx, 4);
  std::vector<Tensor> ts;
  for (const auto& v : tensors) ts.push_back(Tensor::upload(ctx, HostTensor::from_f32({int64_t(v.size())}, v)));
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    for (size_t i = 0; i < ts.size(); ++i) check.record(rec, ts[i], "t" + std::to_string(i), range);
  });
  return check.hits();
}

// Both shader variants: texel-buffer reads (the default where views allow) and the storage-buffer fallback.
class OpsCheck : public test::TexelPathsTest {};
DVS_TEXEL_PATHS(Paths, OpsCheck);

TEST_P(OpsCheck, CountsAndLocatesNonFiniteValues) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  for (size_t n : {size_t(1), size_t(15), size_t(17), size_t(1000), size_t(4099)}) {
    for (int plant = 0; plant < 4; ++plant) {
      std::vector<float> v = random_values(n, uint32_t(n + plant));
      if (plant == 1) v[n - 1] = nan;                       // the last element (an odd tail)
      if (plant == 2) v[n / 2] = -inf, v[n - 1] = inf;      // two, first in the middle
      if (plant == 3) v[0] = -nan;                          // a negative NaN at 0
      const Reference ref = reference(v);
      const auto hits = scan(ctx(), {v});
      if (ref.count == 0) {
        EXPECT_TRUE(hits.empty()) << n << " plant " << plant;
        continue;
      }
      ASSERT_EQ(hits.size(), 1u) << n << " plant " << plant;
      EXPECT_EQ(hits[0].count, ref.count) << n << " plant " << plant;
      EXPECT_EQ(hits[0].first, ref.first) << n << " plant " << plant;
      EXPECT_EQ(hits[0].what, "t0");
    }
  }
}

TEST_P(OpsCheck, SplitScanKeepsGlobalIndices) {
  // 1 MiB ranges over 700k floats: three dispatches; the bad values lie in the 2nd and 3rd ranges only.
  std::vector<float> v = random_values(700000, 3);
  v[600001] = std::numeric_limits<float>::infinity();
  v[300007] = std::numeric_limits<float>::quiet_NaN();
  const auto hits = scan(ctx(), {v}, VkDeviceSize(1) << 20);
  ASSERT_EQ(hits.size(), 1u);
  EXPECT_EQ(hits[0].count, 2u);
  EXPECT_EQ(hits[0].first, 300007);
}

TEST_P(OpsCheck, ValuesPastTheEndAreNotScanned) {
  // A 5-element view whose vec4 reads reach 3 NaN floats that belong to something else.
  std::vector<float> backing(64, 1.0f);
  for (size_t i = 5; i < 64; ++i) backing[i] = std::numeric_limits<float>::quiet_NaN();
  const Tensor all = Tensor::upload(ctx(), HostTensor::from_f32({64}, backing));
  const Tensor five = Tensor::on(all.buffer().sub(0, 5 * sizeof(float)), {5}, DType::f32);
  ops::NonFiniteCheck check(ctx(), 2);
  ops::run_now(ctx(), [&](vk::Recorder& rec) { check.record(rec, five, "five"); });
  EXPECT_TRUE(check.hits().empty());
}

TEST_P(OpsCheck, EachTensorHasItsOwnSlot) {
  std::vector<float> clean = random_values(64, 1), bad = random_values(64, 2);
  bad[9] = std::numeric_limits<float>::quiet_NaN();
  const auto hits = scan(ctx(), {clean, bad, clean});
  ASSERT_EQ(hits.size(), 1u);
  EXPECT_EQ(hits[0].what, "t1");
  EXPECT_EQ(hits[0].first, 9);
}

TEST_P(OpsCheck, RequireFiniteNamesTheTensorAndTheIndex) {
  std::vector<float> v(2 * 3 * 4, 0.5f);
  v[1 * 12 + 2 * 4 + 3] = std::numeric_limits<float>::quiet_NaN();
  const Tensor t = Tensor::upload(ctx(), HostTensor::from_f32({2, 3, 4}, v));
  try {
    ops::require_finite(ctx(), {{&t, "x_init"}}, "check the weights");
    FAIL() << "no error";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("x_init [2,3,4]: 1 non-finite value (NaN/Inf), the first at [1,2,3] (flat index 23)"), std::string::npos) << m;
    EXPECT_NE(m.find("check the weights"), std::string::npos) << m;
  }
  const Tensor ok = Tensor::upload(ctx(), HostTensor::from_f32({3}, std::vector<float>{1, 2, 3}));
  EXPECT_NO_THROW(ops::require_finite(ctx(), {{&ok, "fine"}}));
}

TEST(OpsCheckIndex, FormatsRowMajorIndices) {
  EXPECT_EQ(ops::format_index({13, 16, 60, 90}, 0), "[0,0,0,0]");
  EXPECT_EQ(ops::format_index({13, 16, 60, 90}, 90 * 60 * 16 + 90 * 2 + 5), "[1,0,2,5]");
  EXPECT_EQ(ops::format_index({7}, 6), "[6]");
}

}  // namespace
}  // namespace dvs
