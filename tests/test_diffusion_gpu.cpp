// Diffusion stages on the GPU against the plain C++ reference (krnr_reference, schedule coefficients) on
// random latents of odd sizes, plus loop properties: a stand-in linear model, progress, cancellation.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "diffusion/krnr.hpp"
#include "diffusion/sampler.hpp"
#include "support/gpu.hpp"
#include "support/random_latent.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"

namespace dvs::diffusion {
namespace {

using test::GpuTest;

double max_diff(const std::vector<float>& a, const std::vector<float>& b) {
  double m = 0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::fabs(double(a[i]) - b[i]));
  return m;
}

TEST_F(GpuTest, AdaptiveKrnrPaperMatchesReference) {
  for (Shape s : {Shape{3, 5, 7, 9}, Shape{1, 1, 1, 33}, Shape{13, 4, 3, 5}}) {
    HostTensor x0 = test::random_latent(s, 1, 0.5f), eps = test::random_latent(s, 2);
    reference::LatentShape ls{s[0], s[1], s[2], s[3]};
    for (double abar : {0.0002475, 0.3, 0.9}) {
      Tensor out = adaptive_krnr_paper(ctx(), Tensor::upload(ctx(), x0), Tensor::upload(ctx(), eps), abar, 10, 3);
      auto ref = reference::adaptive_krnr_paper(x0.to_f32(), eps.to_f32(), ls, abar, 10, 3);
      EXPECT_LT(max_diff(out.download(ctx()).to_f32(), ref), 2e-5) << shape_str(s) << " abar " << abar;
    }
  }
}

TEST_F(GpuTest, AdainGivesTheTargetChannelStatistics) {
  Shape s{5, 3, 9, 11};
  HostTensor content = test::random_latent(s, 3, 2.0f), style = test::random_latent(s, 4);
  for (int64_t i = 0; i < style.numel(); ++i) style.as<float>()[i] = style.as<float>()[i] * 0.3f + 1.5f;
  Tensor c = Tensor::upload(ctx(), content), st = Tensor::upload(ctx(), style), out = Tensor::empty(ctx(), s, DType::f32);
  AdainWorkspace ws(ctx(), LatentDims::of(c));
  ops::run_now(ctx(), [&](vk::Recorder& rec) { adain_per_channel(rec, c, st, out, ws); });
  auto stats = [&](const std::vector<float>& v, int64_t ch) {
    double sum = 0, sq = 0;
    int64_t n = 0;
    for (int64_t f = 0; f < s[0]; ++f)
      for (int64_t i = 0; i < s[2] * s[3]; ++i) {
        double x = v[size_t((f * s[1] + ch) * s[2] * s[3] + i)];
        sum += x, sq += x * x, ++n;
      }
    double m = sum / double(n);
    return std::pair{m, std::sqrt(sq / double(n) - m * m)};
  };
  auto o = out.download(ctx()).to_f32(), t = style.to_f32();
  for (int64_t ch = 0; ch < s[1]; ++ch) {
    auto [mo, so] = stats(o, ch);
    auto [mt, stt] = stats(t, ch);
    EXPECT_NEAR(mo, mt, 1e-4);
    EXPECT_NEAR(so, stt, 1e-4);
  }
}

TEST_F(GpuTest, OfficialKrnrMatchesReference) {
  Shape s{3, 4, 5, 7};
  HostTensor x0 = test::random_latent(s, 5), eps = test::random_latent(s, 6), mu = test::random_latent(s, 7), sigma = test::random_latent(s, 8);
  for (int64_t i = 0; i < sigma.numel(); ++i) sigma.as<float>()[i] = 0.1f + std::fabs(sigma.as<float>()[i]);
  const double abar = 0.0002475;
  Tensor out = adaptive_krnr_official(ctx(), Tensor::upload(ctx(), x0), Tensor::upload(ctx(), eps), Tensor::upload(ctx(), mu),
                                      Tensor::upload(ctx(), sigma), abar, 10, 2, 3);
  auto ref = reference::adaptive_krnr_official(x0.to_f32(), eps.to_f32(), mu.to_f32(), sigma.to_f32(), abar, 10, 2, 3);
  EXPECT_LT(max_diff(out.download(ctx()).to_f32(), ref), 1e-5);
  EXPECT_THROW(adaptive_krnr_official(ctx(), Tensor::upload(ctx(), x0), Tensor::upload(ctx(), eps), Tensor::upload(ctx(), mu),
                                      Tensor::upload(ctx(), sigma), abar, 0, 2, 3),
               Error);
}

// Stand-in model: v_uncond = 0.5·x, v_cond = 0.5·x + t/1000; the host repeats the loop in double.
Denoiser linear_model() {
  return [](vk::Recorder& rec, const Tensor& x, int t, const Tensor& v) {
    Tensor rows = v.reshape({v.dim(0), x.numel()});
    ops::scale(rec, x.reshape({1, x.numel()}), rows.rows(0, 1), 0.5f, 0.0f);
    if (v.dim(0) == 2) ops::scale(rec, x.reshape({1, x.numel()}), rows.rows(1, 1), 0.5f, float(t) / 1000.0f);
  };
}

TEST_F(GpuTest, SamplingLoopMatchesHostLoop) {
  CogVideoXSchedule s;
  SamplingPlan plan = s.plan(7, 0.8);
  Shape shape{2, 3, 5, 8};  // the stand-in model binds row views: rows of a multiple of 16 bytes
  HostTensor x = test::random_latent(shape, 9);
  const double g = 4.5;
  SampleResult r = sample(ctx(), Tensor::upload(ctx(), x), s, plan, linear_model(), {true, g});
  std::vector<double> ref(x.numel());
  for (int64_t i = 0; i < x.numel(); ++i) ref[size_t(i)] = x.as<float>()[i];
  std::vector<double> pred(ref.size());
  for (int t : plan.timesteps) {
    StepCoefficients c = s.step(t, plan.num_inference_steps);
    for (size_t i = 0; i < ref.size(); ++i) {
      double u = 0.5 * ref[i], cond = 0.5 * ref[i] + t / 1000.0, v = u + g * (cond - u);
      pred[i] = c.pred_x0.x * ref[i] + c.pred_x0.v * v;
      ref[i] = c.next.x * ref[i] + c.next.v * v;
    }
  }
  auto got = r.latent.download(ctx()).to_f32(), gotp = r.pred_x0.download(ctx()).to_f32();
  for (size_t i = 0; i < ref.size(); ++i) {
    ASSERT_NEAR(got[i], ref[i], 1e-4 * (1 + std::fabs(ref[i]))) << i;
    ASSERT_NEAR(gotp[i], pred[i], 1e-4 * (1 + std::fabs(pred[i]))) << i;
  }
}

TEST_F(GpuTest, InversionLoopMatchesHostLoopAndCancels) {
  CogVideoXSchedule s;
  auto steps = inversion_steps_paper(s, s.plan(10, 0.9).t0(), 6);
  ASSERT_EQ(steps.size(), 6u);
  EXPECT_EQ(steps.front().from_t, -1);
  EXPECT_EQ(steps.back().to_t, s.plan(10, 0.9).t0());
  Shape shape{1, 3, 4, 4};
  HostTensor x = test::random_latent(shape, 10);
  Tensor out = invert(ctx(), Tensor::upload(ctx(), x), steps, linear_model(), {false, 1.0});
  std::vector<double> ref(x.numel());
  for (int64_t i = 0; i < x.numel(); ++i) ref[size_t(i)] = x.as<float>()[i];
  for (const auto& c : steps)
    for (double& r : ref) r = c.next.x * r + c.next.v * 0.5 * r;
  auto got = out.download(ctx()).to_f32();
  for (size_t i = 0; i < ref.size(); ++i) ASSERT_NEAR(got[i], ref[i], 1e-4 * (1 + std::fabs(ref[i])));

  LoopCallbacks cb;
  int calls = 0;
  cb.cancelled = [&] { return ++calls > 2; };
  EXPECT_THROW(invert(ctx(), Tensor::upload(ctx(), x), steps, linear_model(), {false, 1.0}, cb), Cancelled);
  EXPECT_EQ(calls, 3);
}

}  // namespace
}  // namespace dvs::diffusion
