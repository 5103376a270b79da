// Diffusion-side dispatches split within one binding: AdaIN (statistics by windowed reductions, the apply
// pass over channel-plane ranges) and the official K-RNR round (element ranges). Under binding=2KiB the
// latents below span several bindings; results match the call under the limits in force before (K-RNR
// bitwise; AdaIN within fp32 rounding, the reduction blocks may differ), with more dispatches.
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <vector>

#include "diffusion/krnr.hpp"
#include "support/gpu.hpp"
#include "support/random_latent.hpp"
#include "support/split_check.hpp"

namespace dvs::diffusion {
namespace {

constexpr const char* kSplitLimits = "binding=2KiB,groups=64";

class SplitDiffusion : public test::GpuTest {};

TEST_F(SplitDiffusion, KrnrOfficialRoundSplitsOverElementRanges) {
  const Shape s{3, 5, 7, 9};  // 945 elements: 3780 bytes
  auto latent = [&](uint32_t seed) { return Tensor::upload(ctx(), test::random_latent(s, seed)); };
  const Tensor x0 = latent(1), eps = latent(2), mu = latent(3), sigma = latent(4);
  test::expect_split_equal(ctx(), kSplitLimits, s, DType::f32, [&](vk::Recorder& r, const Tensor& out) {
    krnr_official_round(r, x0, eps, mu, sigma, {0.7, 0.3}, {0.9, 0.1}, out);
  }, "krnr_official_round");
}

TEST_F(SplitDiffusion, AdainSplitsOverChannelPlanes) {
  const Shape s{5, 3, 9, 11};  // planes of 99 elements, 5940 bytes in all
  const Tensor content = Tensor::upload(ctx(), test::random_latent(s, 5, 2.0f));
  const Tensor style = Tensor::upload(ctx(), test::random_latent(s, 6));
  std::vector<float> out[2];
  uint32_t dispatches[2];
  for (int i = 0; i < 2; ++i) {
    std::optional<test::ScopedLimits> limits;
    if (i == 1) limits.emplace(ctx(), kSplitLimits);
    const AdainWorkspace ws(ctx(), LatentDims::of(content));
    const Tensor o = Tensor::empty(ctx(), s, DType::f32);
    dispatches[i] = test::run_counted(ctx(), [&](vk::Recorder& r) { adain_per_channel(r, content, style, o, ws); });
    out[i] = o.download(ctx()).to_f32();
  }
  EXPECT_GT(dispatches[1], dispatches[0]);
  for (size_t k = 0; k < out[0].size(); ++k)
    ASSERT_NEAR(out[1][k], out[0][k], 1e-5 * (1 + std::fabs(out[0][k]))) << "element " << k;
}

}  // namespace
}  // namespace dvs::diffusion
