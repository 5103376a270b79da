// Unit tests of the host diffusion math: schedules (timesteps, strength truncation, step coefficients,
// edge cases, config errors) and the K-RNR reference (closed form = recursion, AdaIN statistics, the
// official analytic AdaIN's cancellation of k). Values from docs/design.md §9 (tables A, B).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "diffusion/krnr_reference.hpp"
#include "diffusion/schedule.hpp"
#include "dvs/error.hpp"

using namespace dvs::diffusion;
namespace ref = dvs::diffusion::reference;

namespace {

using dvs::test::error_of;

std::vector<float> randn(size_t n, uint32_t seed, float scale = 1.0f, float offset = 0.0f) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> d(0.0f, 1.0f);
  std::vector<float> v(n);
  for (float& x : v) x = offset + scale * d(rng);
  return v;
}

const CogVideoXSchedule& cog() {
  static CogVideoXSchedule s{SchedulerConfig{}};
  return s;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------
// schedules

TEST(Schedule, TrailingTimestepsOfficialS30) {
  const std::vector<int> expect = {999, 966, 932, 899, 866, 832, 799, 766, 732, 699, 666, 632, 599, 566, 532,
                                   499, 466, 432, 399, 366, 332, 299, 266, 232, 199, 166, 132, 99,  66,  32};
  EXPECT_EQ(cog().timesteps(30), expect);
  const auto t50 = cog().timesteps(50);
  ASSERT_EQ(t50.size(), 50u);
  EXPECT_EQ(t50.front(), 999);
  EXPECT_EQ(t50[1], 979);
  EXPECT_EQ(t50.back(), 19);
}

TEST(Schedule, TrailingTimestepsEveryStepCount) {
  // numpy's arange gives S + 1 values for some S (61, 103, ...); we keep S, strictly descending, from 999.
  for (int S = 1; S <= 1000; ++S) {
    const auto ts = trailing_timesteps(1000, S);
    ASSERT_EQ(ts.size(), size_t(S));
    EXPECT_EQ(ts.front(), 999) << S;
    EXPECT_GE(ts.back(), 0) << S;
    for (size_t i = 1; i < ts.size(); ++i) ASSERT_LT(ts[i], ts[i - 1]) << S;
  }
  EXPECT_EQ(trailing_timesteps(1000, 1000).back(), 0);
}

TEST(Schedule, AlphasCumprodAppendixA) {
  const struct {
    int t;
    double v;
  } table[] = {{966, 2.475362e-4}, {932, 1.184161e-3}, {499, 0.2423592}, {33, 0.9666653}, {0, 0.9991500}, {979, 8.578784e-5}};
  for (const auto& e : table) EXPECT_NEAR(cog().alpha_cumprod(e.t), e.v, e.v * 1e-6) << e.t;
  EXPECT_EQ(cog().alpha_cumprod(999), 0.0);
  EXPECT_EQ(cog().alpha_cumprod(-1), 1.0);  // set_alpha_to_one
  EXPECT_NE(error_of([] { cog().alpha_cumprod(1000); }), "");
}

TEST(Schedule, InverseFloat32TableCloseToFloat64) {
  const DDIMInverseSchedule inv{SchedulerConfig{}};
  double m = 0;
  for (int t = 0; t < 1000; ++t) m = std::max(m, std::fabs(double(inv.alphas_cumprod()[size_t(t)]) - cog().alpha_cumprod(t)));
  EXPECT_LT(m, 6e-7);  // docs/design.md §6.4: "within 4.7e-7" (plus float32 rounding of the value)
  EXPECT_EQ(inv.alphas_cumprod().back(), 0.0f);
  const auto ts = inv.timesteps(30);
  EXPECT_EQ(ts.front(), 32);
  EXPECT_EQ(ts.back(), 999);
}

TEST(Schedule, SnrShiftBeforeRescale) {
  SchedulerConfig c;
  c.snr_shift_scale = 3.0;
  const CogVideoXSchedule s(c);
  EXPECT_EQ(s.alpha_cumprod(999), 0.0);  // the rescale comes last, so the terminal SNR is still zero
  // Without rescale the shift is the plain SD3 formula.
  c.rescale_betas_zero_snr = false;
  SchedulerConfig plain = c;
  plain.snr_shift_scale = 1.0;
  const CogVideoXSchedule shifted(c), unshifted(plain);
  for (int t : {0, 500, 999}) {
    const double a = unshifted.alpha_cumprod(t);
    EXPECT_NEAR(shifted.alpha_cumprod(t), a / (3.0 + (1 - 3.0) * a), 1e-15);
  }
}

TEST(Schedule, StrengthTruncation) {
  SamplingPlan p = cog().plan(30, 0.98);
  EXPECT_EQ(p.t0(), 966);
  EXPECT_EQ(p.num_steps(), 29);
  EXPECT_EQ(p.num_inference_steps, 30);
  p = cog().plan(50, 0.98);
  EXPECT_EQ(p.t0(), 979);
  EXPECT_EQ(p.num_steps(), 49);
  p = cog().plan(50, 0.95);  // paper: keeps floor(47.5) = 47
  EXPECT_EQ(p.num_steps(), 47);
  p = cog().plan(4, 0.95);
  EXPECT_EQ(p.timesteps, (std::vector<int>{749, 499, 249}));
  p = cog().plan(1, 1.0);
  EXPECT_EQ(p.timesteps, (std::vector<int>{999}));
  p = cog().plan(30, 1.0);
  EXPECT_EQ(p.num_steps(), 30);
}

TEST(Schedule, StrengthErrors) {
  const std::string msg = error_of([] { cog().plan(4, 0.2); });
  EXPECT_NE(msg.find("keeps no sampling step"), std::string::npos) << msg;
  EXPECT_NE(error_of([] { cog().plan(1, 0.99); }), "");
  EXPECT_NE(error_of([] { cog().plan(30, 0.0); }), "");
  EXPECT_NE(error_of([] { cog().plan(30, -0.5); }), "");
  EXPECT_NE(error_of([] { cog().plan(30, 1.5); }), "");
  EXPECT_NE(error_of([] { cog().plan(30, std::nan("")); }), "");
  EXPECT_NE(error_of([] { cog().plan(0, 1.0); }), "");
  EXPECT_NE(error_of([] { cog().plan(1001, 1.0); }), "");
}

TEST(Schedule, StepCoefficients) {
  // S = 30: prev_t = t − 33 (docs/design.md §9, table A); the library's x0 form equals the generic DDIM transfer.
  for (int t : {966, 932, 499, 66}) {
    const StepCoefficients c = cog().step(t, 30);
    EXPECT_EQ(c.to_t, t - 33);
    const StepCoefficients g = ddim_transfer(cog().alpha_cumprod(t), cog().alpha_cumprod(t - 33), PredictionType::v_prediction);
    EXPECT_NEAR(c.next.x, g.next.x, 1e-12);
    EXPECT_NEAR(c.next.v, g.next.v, 1e-12);
    EXPECT_NEAR(c.pred_x0.x, std::sqrt(cog().alpha_cumprod(t)), 1e-15);
    EXPECT_NEAR(c.pred_x0.v, -std::sqrt(1 - cog().alpha_cumprod(t)), 1e-15);
  }
  // Last step (prev_t < 0): ᾱ_prev = 1, so x_prev = x̂0.
  const StepCoefficients last = cog().step(32, 30);
  EXPECT_EQ(last.to_t, -1);
  EXPECT_NEAR(last.next.x, last.pred_x0.x, 1e-15);
  EXPECT_NEAR(last.next.v, last.pred_x0.v, 1e-15);
  // S = 1, t = 999 (ᾱ = 0): x̂0 = −v, x_prev = x̂0.
  const StepCoefficients one = cog().step(999, 1);
  EXPECT_EQ(one.to_t, -1);
  EXPECT_NEAR(one.next.x, 0.0, 1e-15);
  EXPECT_NEAR(one.next.v, -1.0, 1e-15);
}

TEST(Schedule, InverseStepCoefficients) {
  const DDIMInverseSchedule inv{SchedulerConfig{}};
  // Target t = 32 with S = 30: source s = −1 → clean level, ᾱ_s = 1: x̂0 = x, ε̂ = v.
  StepCoefficients c = inv.step(32, 30);
  EXPECT_EQ(c.from_t, -1);
  EXPECT_EQ(c.model_t, 32);
  EXPECT_EQ(c.pred_x0.x, 1.0);
  EXPECT_EQ(c.pred_x0.v, 0.0);
  // Target 999 (ᾱ = 0): the output is the ε prediction at s = 966.
  c = inv.step(999, 30);
  EXPECT_EQ(c.from_t, 966);
  const double as = inv.alphas_cumprod()[966];
  EXPECT_NEAR(c.next.x, std::sqrt(1 - as), 1e-7);
  EXPECT_NEAR(c.next.v, std::sqrt(as), 1e-7);
}

TEST(Schedule, SingleStep) {
  // S = 1 both ways: sampling 999 → clean, inversion clean → 999 (ᾱ = 0: the output is the model output).
  EXPECT_EQ(cog().timesteps(1), (std::vector<int>{999}));
  const DDIMInverseSchedule inv{SchedulerConfig{}};
  EXPECT_EQ(inv.timesteps(1), (std::vector<int>{999}));
  const StepCoefficients c = inv.step(999, 1);
  EXPECT_EQ(c.from_t, -1);
  EXPECT_EQ(c.next.x, 0.0);
  EXPECT_EQ(c.next.v, 1.0);
  EXPECT_EQ(CogVideoXSchedule::paper_inversion_timesteps(966, 1), (std::vector<int>{966}));
}

TEST(Schedule, OtherSpacings) {
  SchedulerConfig c;
  c.timestep_spacing = TimestepSpacing::leading;
  c.steps_offset = 1;
  EXPECT_EQ(CogVideoXSchedule(c).timesteps(4), (std::vector<int>{751, 501, 251, 1}));
  EXPECT_EQ(DDIMInverseSchedule(c).timesteps(4), (std::vector<int>{1, 251, 501, 751}));
  c.timestep_spacing = TimestepSpacing::linspace;  // np.linspace(0, 999, 5).round()[::-1], half to even
  EXPECT_EQ(CogVideoXSchedule(c).timesteps(5), (std::vector<int>{999, 749, 500, 250, 0}));
  EXPECT_NE(error_of([&] { DDIMInverseSchedule(c).timesteps(5); }), "");
}

TEST(Schedule, PaperInversion) {
  const auto ts = CogVideoXSchedule::paper_inversion_timesteps(966, 30);
  ASSERT_EQ(ts.size(), 30u);
  EXPECT_EQ(ts.front(), 31);  // round(967/30) − 1
  EXPECT_EQ(ts.back(), 966);
  for (size_t i = 1; i < ts.size(); ++i) EXPECT_LT(ts[i - 1], ts[i]);
  EXPECT_EQ(CogVideoXSchedule::paper_inversion_timesteps(0, 1), (std::vector<int>{0}));
  EXPECT_EQ(CogVideoXSchedule::paper_inversion_timesteps(3, 4), (std::vector<int>{0, 1, 2, 3}));
  EXPECT_NE(error_of([] { CogVideoXSchedule::paper_inversion_timesteps(3, 5); }), "");
  EXPECT_NE(error_of([] { CogVideoXSchedule::paper_inversion_timesteps(100, 0); }), "");
  // First step from the clean latent: x̂0 = x and ε̂ = v, so x_t = √ᾱ_t·x + √(1 − ᾱ_t)·v.
  const StepCoefficients c = cog().inversion_step(-1, ts[0], -1);
  EXPECT_NEAR(c.next.x, std::sqrt(cog().alpha_cumprod(ts[0])), 1e-15);
  EXPECT_NEAR(c.next.v, std::sqrt(1 - cog().alpha_cumprod(ts[0])), 1e-15);
  EXPECT_NE(error_of([&] { cog().inversion_step(500, 400, 400); }), "");
}

TEST(Schedule, ConfigFiles) {
  SchedulerConfig c = parse_scheduler_config(R"({"snr_shift_scale": 3.0, "rescale_betas_zero_snr": false})", "inline");
  EXPECT_EQ(c.snr_shift_scale, 3.0);
  EXPECT_FALSE(c.rescale_betas_zero_snr);
  EXPECT_NE(error_of([] { parse_scheduler_config("{oops", "bad.json"); }).find("bad.json"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scheduler_config(R"({"beta_schedule": "squaredcos_cap_v2"})", "x.json"); }).find("beta_schedule"),
            std::string::npos);
  EXPECT_NE(error_of([] { parse_scheduler_config(R"({"prediction_type": "flow"})", "x.json"); }).find("prediction_type"),
            std::string::npos);
  const std::string msg = error_of([] { load_scheduler_config("/nonexistent/model"); });
  EXPECT_NE(msg.find("scheduler_config.json"), std::string::npos) << msg;
}

// ---------------------------------------------------------------------------------------------------------
// K-RNR reference

TEST(KrnrReference, ClosedFormEqualsRecursion) {
  const size_t n = 3 * 4 * 5 * 7;
  const auto x0 = randn(n, 1), eps = randn(n, 2);
  for (double abar : {cog().alpha_cumprod(966), cog().alpha_cumprod(749), 0.5, 0.999}) {
    for (int k : {0, 1, 2, 3, 6, 10, 20}) {
      const auto closed = ref::krnr(x0, eps, abar, double(k));
      const auto rec = ref::krnr_recursion(x0, eps, abar, k);
      for (size_t i = 0; i < n; ++i) ASSERT_NEAR(closed[i], rec[i], 2e-6) << "abar " << abar << " k " << k;
      const auto a = ref::krnr_closed_form(abar, k), b = ref::krnr_series(abar, k);
      EXPECT_NEAR(a.m, b.m, 1e-12);
      EXPECT_NEAR(a.n, b.n, 1e-15);
    }
  }
}

TEST(KrnrReference, CoefficientsAppendixB) {
  const double abar = cog().alpha_cumprod(966);
  const struct {
    int k;
    double m, n;
  } table[] = {{2, 0.031465, 0.999752}, {5, 0.078647, 0.999381}, {6, 0.094370, 0.999258}, {10, 0.157245, 0.998763}};
  for (const auto& e : table) {
    const auto c = ref::krnr_closed_form(abar, e.k);
    EXPECT_NEAR(c.m, e.m, 1e-6) << e.k;
    EXPECT_NEAR(c.n, e.n, 1e-6) << e.k;
  }
  // Continuous k: n = b^k and m·(1 − b) = a·(1 − n).
  const auto c = ref::krnr_closed_form(abar, 2.5);
  const double a = std::sqrt(abar), b = std::sqrt(1 - abar);
  EXPECT_NEAR(c.n, std::pow(b, 2.5), 1e-15);
  EXPECT_NEAR(c.m * (1 - b), a * (1 - c.n), 1e-15);
  // ᾱ = 0 (b = 1): no x0 contribution; ᾱ = 1 (b = 0): ε^(k) = x0 for k ≥ 1.
  EXPECT_EQ(ref::krnr_closed_form(0.0, 10).m, 0.0);
  EXPECT_EQ(ref::krnr_closed_form(0.0, 10).n, 1.0);
  EXPECT_NEAR(ref::krnr_closed_form(1.0, 3).m, 1.0, 1e-15);
  EXPECT_EQ(ref::krnr_closed_form(1.0, 3).n, 0.0);
  EXPECT_NE(error_of([] { ref::krnr_closed_form(1.5, 3); }), "");
  EXPECT_NE(error_of([] { ref::krnr_closed_form(0.5, -1); }), "");
}

TEST(KrnrReference, AdainMatchesTargetStatistics) {
  const ref::LatentShape s{3, 5, 7, 9};
  const size_t n = size_t(s.numel());
  auto content = randn(n, 3, 2.0f, 0.5f), style = randn(n, 4, 0.3f, -1.0f);
  // Give each channel its own style statistics.
  for (int64_t f = 0; f < s.frames; ++f)
    for (int64_t c = 0; c < s.channels; ++c)
      for (int64_t p = 0; p < s.height * s.width; ++p) {
        float& v = style[size_t((f * s.channels + c) * s.height * s.width + p)];
        v = v * float(1 + c) + float(c);
      }
  for (double eps : {0.0, 1e-6}) {
    const auto out = ref::adain_per_channel(content, style, s, eps);
    for (int64_t c = 0; c < s.channels; ++c) {
      auto stats = [&](const std::vector<float>& v) {
        double sum = 0, sq = 0;
        const int64_t count = s.frames * s.height * s.width;
        for (int64_t f = 0; f < s.frames; ++f)
          for (int64_t p = 0; p < s.height * s.width; ++p) sum += v[size_t((f * s.channels + c) * s.height * s.width + p)];
        const double mean = sum / double(count);
        for (int64_t f = 0; f < s.frames; ++f)
          for (int64_t p = 0; p < s.height * s.width; ++p) {
            const double d = v[size_t((f * s.channels + c) * s.height * s.width + p)] - mean;
            sq += d * d;
          }
        return std::pair<double, double>{mean, std::sqrt(sq / double(count))};
      };
      const auto [mo, so] = stats(out);
      const auto [ms, ss] = stats(style);
      EXPECT_NEAR(mo, ms, 1e-5) << "channel " << c;
      EXPECT_NEAR(so, ss, 1e-5 * (1 + ss)) << "channel " << c << " eps " << eps;
    }
  }
  // A constant content channel: finite with eps > 0, an error with eps = 0.
  std::vector<float> flat(n, 1.0f);
  for (float v : ref::adain_per_channel(flat, style, s, 1e-6)) ASSERT_TRUE(std::isfinite(v));
  EXPECT_NE(error_of([&] { ref::adain_per_channel(flat, style, s, 0.0); }), "");
  EXPECT_NE(error_of([&] { ref::adain_per_channel(content, style, ref::LatentShape{1, 1, 1, 1}, 1e-6); }), "");
}

TEST(KrnrReference, OfficialRoundCancelsK) {
  // (noisy − cur_mean)/cur_std·tgt_std + tgt_mean = m_δ·x0 + n_δ·ε for any k (up to the 1e-9).
  const size_t n = 4 * 4 * 6 * 6;
  const auto x0 = randn(n, 5), eps = randn(n, 6), mu = randn(n, 7);
  auto sigma = randn(n, 8, 0.1f);
  for (float& s : sigma) s = 0.2f + std::fabs(s);
  const double abar = cog().alpha_cumprod(966);
  const auto c2 = ref::krnr_series(abar, 2);
  for (int k : {5, 10, 20}) {
    const auto out = ref::adaptive_krnr_official_round(x0, eps, mu, sigma, abar, k, 2);
    const auto expect = ref::combine(x0, eps, c2);
    for (size_t i = 0; i < n; ++i) ASSERT_NEAR(out[i], expect[i], 1e-5) << "k " << k;
  }
  // Three rounds compose to order 6: m_6·x0 + n_6·ε.
  const auto three = ref::adaptive_krnr_official(x0, eps, mu, sigma, abar, 10, 2, 3);
  const auto c6 = ref::krnr_series(abar, 6);
  const auto expect6 = ref::combine(x0, eps, c6);
  for (size_t i = 0; i < n; ++i) ASSERT_NEAR(three[i], expect6[i], 1e-5);
  EXPECT_EQ(ref::adaptive_krnr_official(x0, eps, mu, sigma, abar, 10, 2, 0), eps);
  EXPECT_NE(error_of([&] { ref::adaptive_krnr_official_round(x0, std::vector<float>(3), mu, sigma, abar, 10, 2); }), "");
}
