// The diffusion stages as separate calls (sampler guidance modes, init_noise) and their edge cases, against
// plain C++ references and the independent tables of docs/design.md §9 (tables A, C):
//  - the official dynamic guidance scale, per step, against table C;
//  - the fused guidance + DDIM step on the GPU (constant and position-wise dynamic) against a host loop on
//    random model outputs of odd sizes;
//  - S = 1, strength 1.0, a strength that keeps no step (the error names the option);
//  - K-RNR's closed form on the GPU against the recursion for integer k;
//  - init_noise for both presets against the previous inline pipeline code and a host reference;
//  - P for the dynamic CFG (positions_to_replace) from the SLM masks.
// (AdaIN statistics, SLM properties and reproducibility: test_diffusion_gpu.cpp, test_slm.cpp, test_schedule.cpp.)
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "diffusion/init_noise.hpp"
#include "diffusion/krnr.hpp"
#include "diffusion/sampler.hpp"
#include "dvs/error.hpp"
#include "support/gpu.hpp"
#include "support/random_latent.hpp"
#include "support/scoped_limits.hpp"
#include "tensor/dispatch.hpp"

namespace dvs::diffusion {
namespace {

using test::GpuTest;

using dvs::test::error_of;

double max_rel_diff(const std::vector<float>& a, const std::vector<double>& b) {
  double m = 0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::fabs(double(a[i]) - b[i]) / (1 + std::fabs(b[i])));
  return m;
}

// ---------------------------------------------------------------------------------------------------------
// g_dyn against docs/design.md §9 table C (S = 30, strength 0.98: N = 29, t from table A).

TEST(DynamicGuidance, ScaleMatchesAppendixC) {
  const int ts[29] = {966, 932, 899, 866, 832, 799, 766, 732, 699, 666, 632, 599, 566, 532, 499,
                      466, 432, 399, 366, 332, 299, 266, 232, 199, 166, 132, 99,  66,  32};
  const struct {
    double g;
    double v[29];
  } table[] = {
      {6, {4.941, 1.021, 7.000, 1.004, 1.764, 6.820, 1.005, 1.273, 5.974, 3.506, 1.439, 6.517, 2.602, 5.899, 6.992,
           1.369, 1.301, 2.548, 6.937, 3.294, 2.877, 3.532, 1.000, 5.218, 1.036, 1.530, 6.948, 2.903, 7.000}},
      {10, {7.569, 1.035, 11.000, 1.007, 2.274, 10.700, 1.009, 1.456, 9.290, 5.177, 1.731, 10.194, 3.670, 9.166, 10.987,
            1.614, 1.501, 3.580, 10.894, 4.823, 4.128, 5.219, 1.000, 8.030, 1.060, 1.884, 10.914, 4.171, 11.000}},
      {12, {8.883, 1.041, 13.000, 1.008, 2.529, 12.641, 1.011, 1.547, 10.948, 6.012, 1.877, 12.033, 4.205, 10.799,
            12.985, 1.737, 1.602, 4.096, 12.873, 5.588, 4.754, 6.063, 1.000, 9.435, 1.072, 2.061, 12.897, 4.805, 13.000}},
  };
  for (const auto& row : table)
    for (int i = 0; i < 29; ++i) {
      const double got = dynamic_guidance_scale(row.g, ts[i], 29);
      EXPECT_NEAR(got, row.v[i], 5.01e-4) << "g " << row.g << " t " << ts[i];
      EXPECT_GE(got, 1.0 - 1e-12);
      EXPECT_LE(got, row.g + 1 + 1e-12);
    }
  // The plan those t come from (table A): S = 30, strength 0.98 keeps N = 29 steps from 966.
  const SamplingPlan plan = CogVideoXSchedule().plan(30, 0.98);
  ASSERT_EQ(plan.num_steps(), 29);
  for (int i = 0; i < 29; ++i) EXPECT_EQ(plan.timesteps[size_t(i)], ts[i]);
}

// ---------------------------------------------------------------------------------------------------------
// Guided sampling: the fused combine + step against a host loop in double.

// Model outputs drawn per timestep (independent of x), written as the two CFG rows.
struct RandomModel {
  Shape latent;
  std::vector<std::vector<float>> u, c;  // per call, in call order
  void operator()(vk::Recorder&, const Tensor&, int t, const Tensor& v) {
    HostTensor hu = test::random_latent(latent, uint32_t(2 * t + 1)), hc = test::random_latent(latent, uint32_t(2 * t + 2));
    u.push_back(hu.to_f32());
    c.push_back(hc.to_f32());
    Shape vs = latent;
    vs.insert(vs.begin(), 2);
    std::vector<float> both = u.back();
    both.insert(both.end(), c.back().begin(), c.back().end());
    v.write(test::gpu(), HostTensor::from_f32(vs, both));  // host write, before this step's recording runs
  }
};

struct HostLoop {
  std::vector<double> x, pred;
};

// The reference loop: ĝ = where(P, u + g_dyn·(c − u), u + p·(c − u)) (or u + g·(c − u)), then the schedule's
// linear step in double.
HostLoop host_sample(const HostTensor& x_init, const CogVideoXSchedule& s, const SamplingPlan& plan, const RandomModel& m,
                     const Guidance& g, const std::vector<float>& positions) {
  HostLoop h;
  for (float v : x_init.to_f32()) h.x.push_back(v);
  h.pred.resize(h.x.size());
  for (size_t step = 0; step < plan.timesteps.size(); ++step) {
    const int t = plan.timesteps[step];
    const StepCoefficients c = s.step(t, plan.num_inference_steps);
    const double N = plan.num_steps();
    const double gd = g.scale + 2 - (1 + g.scale * (1 - std::cos(std::numbers::pi * std::pow((N - t) / N, 5.0))) / 2);
    for (size_t i = 0; i < h.x.size(); ++i) {
      const double u = m.u[step][i], co = m.c[step][i];
      const double scale = g.mode == GuidanceMode::constant ? g.scale : positions[i] != 0 ? gd : g.preservation_scale;
      const double v = u + scale * (co - u);
      h.pred[i] = c.pred_x0.x * h.x[i] + c.pred_x0.v * v;
      h.x[i] = c.next.x * h.x[i] + c.next.v * v;
    }
  }
  return h;
}

void check_sampling(vk::Context& ctx, const SamplingPlan& plan, Guidance g, const std::vector<float>& positions,
                    const std::string& what) {
  const Shape shape{3, 5, 7, 9};  // odd everywhere
  const CogVideoXSchedule s;
  const HostTensor x = test::random_latent(shape, 77);
  RandomModel m{shape, {}, {}};
  if (g.mode == GuidanceMode::dynamic) g.positions = Tensor::upload(ctx, HostTensor::from_f32(shape, positions));
  int progress = 0;
  LoopCallbacks cb;
  cb.progress = [&](int step, int total, int) {
    EXPECT_EQ(total, plan.num_steps());
    progress = step;
  };
  const SampleResult r = sample(ctx, Tensor::upload(ctx, x), s, plan, std::ref(m), g, cb);
  EXPECT_EQ(progress, plan.num_steps()) << what;
  const HostLoop h = host_sample(x, s, plan, m, g, positions);
  ASSERT_EQ(size_t(r.latent.numel()), h.x.size());
  ASSERT_EQ(size_t(m.u.size()), size_t(plan.num_steps())) << "one model call per step";
  EXPECT_LT(max_rel_diff(r.latent.download(ctx).to_f32(), h.x), 2e-5) << what;
  EXPECT_LT(max_rel_diff(r.pred_x0.download(ctx).to_f32(), h.pred), 2e-5) << what;
}

std::vector<float> random_positions(int64_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<float> p(static_cast<size_t>(n));
  for (float& v : p) v = float(rng() % 2);
  return p;
}

TEST_F(GpuTest, GuidedStepConstantMatchesHostLoop) {
  const CogVideoXSchedule s;
  check_sampling(ctx(), s.plan(7, 0.8), {true, 4.5}, {}, "constant, 7 steps at 0.8");
}

TEST_F(GpuTest, GuidedStepDynamicMatchesHostLoop) {
  const CogVideoXSchedule s;
  const int64_t n = 3 * 5 * 7 * 9;
  Guidance g{true, 6.0};
  g.mode = GuidanceMode::dynamic;
  g.preservation_scale = 1.0;
  check_sampling(ctx(), s.plan(30, 0.98), g, random_positions(n, 5), "dynamic, official plan, p = 1");
  g.preservation_scale = 0.3;
  g.scale = 10;
  check_sampling(ctx(), s.plan(9, 0.9), g, random_positions(n, 6), "dynamic, p = 0.3, g = 10");
  check_sampling(ctx(), s.plan(9, 0.9), g, std::vector<float>(size_t(n), 0.0f), "dynamic, P empty");
  check_sampling(ctx(), s.plan(9, 0.9), g, std::vector<float>(size_t(n), 1.0f), "dynamic, P everywhere");
}

// The guided step over element ranges: under binding=1KiB the two-row model output (7560 bytes) and the
// latent span several bindings, which the unsplit dispatch could not bind (the Recorder would refuse it).
TEST_F(GpuTest, GuidedStepSplitsOverElementRanges) {
  const CogVideoXSchedule s;
  test::ScopedLimits limits(ctx(), "binding=1KiB,groups=64");
  Guidance g{true, 6.0};
  g.mode = GuidanceMode::dynamic;
  g.preservation_scale = 0.3;
  check_sampling(ctx(), s.plan(9, 0.9), g, random_positions(3 * 5 * 7 * 9, 7), "dynamic, split");
  check_sampling(ctx(), s.plan(5, 1.0), {true, 6.0}, {}, "constant, split");
}

TEST_F(GpuTest, SamplingEdgeCases) {
  const CogVideoXSchedule s;
  // S = 1: one step from t = 999 (ᾱ = 0) straight to the clean level: x = x̂0 = −ĝ.
  check_sampling(ctx(), s.plan(1, 1.0), {true, 6.0}, {}, "S = 1");
  // Strength 1.0 keeps every step, from 999.
  const SamplingPlan all = s.plan(5, 1.0);
  EXPECT_EQ(all.num_steps(), 5);
  EXPECT_EQ(all.t0(), 999);
  check_sampling(ctx(), all, {true, 6.0}, {}, "strength 1.0");
  // A strength that keeps no step: the error names the options to change.
  const std::string msg = error_of([&] { s.plan(10, 0.05); });
  EXPECT_NE(msg.find("RunOptions::strength"), std::string::npos) << msg;
  EXPECT_NE(msg.find("RunOptions::steps"), std::string::npos) << msg;
  // An empty plan and a dynamic guidance without positions are refused.
  const Tensor x = Tensor::upload(ctx(), test::random_latent({1, 4, 4, 4}, 1));
  RandomModel m{{1, 4, 4, 4}, {}, {}};
  EXPECT_NE(error_of([&] { sample(ctx(), x, s, SamplingPlan{10, {}}, std::ref(m), {true, 6.0}); }).find("RunOptions::strength"),
            std::string::npos);
  Guidance g{true, 6.0};
  g.mode = GuidanceMode::dynamic;
  EXPECT_NE(error_of([&] { sample(ctx(), x, s, s.plan(4, 1.0), std::ref(m), g); }).find("positions"), std::string::npos);
}

// ---------------------------------------------------------------------------------------------------------
// K-RNR on the GPU: closed form (real k) = the unrolled recursion for integer k.

TEST_F(GpuTest, KrnrClosedFormEqualsRecursionOnGpu) {
  const Shape shape{3, 5, 7, 9};
  const HostTensor x0 = test::random_latent(shape, 11), eps = test::random_latent(shape, 12);
  const Tensor dx0 = Tensor::upload(ctx(), x0), deps = Tensor::upload(ctx(), eps), out = Tensor::empty(ctx(), shape, DType::f32);
  for (double abar : {CogVideoXSchedule().alpha_cumprod(966), 0.3, 0.9})
    for (int k : {1, 2, 3, 6, 10}) {
      ops::run_now(ctx(), [&](vk::Recorder& rec) { krnr_combine(rec, dx0, deps, reference::krnr_closed_form(abar, k), out); });
      // ε^(j) = a·x0 + b·ε^(j−1), k times, in double.
      const double a = std::sqrt(abar), b = std::sqrt(1 - abar);
      const auto xv = x0.to_f32(), ev = eps.to_f32();
      std::vector<double> want(xv.size());
      for (size_t i = 0; i < xv.size(); ++i) {
        double e = ev[i];
        for (int j = 0; j < k; ++j) e = a * xv[i] + b * e;
        want[i] = e;
      }
      EXPECT_LT(max_rel_diff(out.download(ctx()).to_f32(), want), 1e-5) << "abar " << abar << " k " << k;
    }
}

// ---------------------------------------------------------------------------------------------------------
// init_noise

struct NoiseCase {
  Shape shape{3, 4, 5, 6};  // F, C, H, W
  HostTensor x0, eps, mu, sigma;
  std::vector<uint8_t> x0_target, x0_source, eps_target, eps_source;
  SlmPlan plan;
  double abar = CogVideoXSchedule().alpha_cumprod(966);

  explicit NoiseCase(vk::Context& ctx) {
    x0 = test::random_latent(shape, 21);
    eps = test::random_latent(shape, 22);
    mu = test::random_latent(shape, 23);
    sigma = test::random_latent(shape, 24);
    for (int64_t i = 0; i < sigma.numel(); ++i) sigma.as<float>()[i] = 0.1f + std::fabs(sigma.as<float>()[i]);
    const int cells = int(shape[0] * shape[2] * shape[3]);
    std::mt19937 rng(25);
    for (int i = 0; i < cells; ++i) {
      const unsigned r = rng() % 4;  // x0: ~¼ occluded; ε: a subset of those
      x0_target.push_back(r == 0);
      x0_source.push_back(r != 0);
      eps_target.push_back(r == 0 && (rng() % 2));
      eps_source.push_back(!eps_target.back());
    }
    plan.latent_shape = shape;
    plan.x0 = make_slm_index_plan(ctx, x0_target, x0_source, int(shape[0]), int(shape[2]), int(shape[3]), int(shape[1]),
                                  SlmOptions::Scope::global, "x0");
    plan.eps = make_slm_index_plan(ctx, eps_target, eps_source, int(shape[0]), int(shape[2]), int(shape[3]),
                                   int(shape[1]), SlmOptions::Scope::global, "eps");
  }
};

// The pipeline's steps 6–7 as they were inline in run_pipeline.cpp before init_noise existed.
Tensor previous_inline(vk::Context& ctx, const NoiseCase& nc, bool official, const Tensor& x0, const Tensor& eps_inv,
                       const Tensor& mu, const Tensor& sigma, uint64_t seed, double k, double delta) {
  const Shape lat = nc.shape;
  Tensor x0_mod = Tensor::empty(ctx, lat, DType::f32, "x0"), eps_mod = Tensor::empty(ctx, lat, DType::f32, "eps");
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    rec.copy(x0.buffer(), x0_mod.buffer(), x0.bytes());
    rec.copy(eps_inv.buffer(), eps_mod.buffer(), eps_inv.bytes());
  });
  if (!official) {
    ops::run_now(ctx, [&](vk::Recorder& rec) { apply_slm(rec, x0_mod, eps_mod, nc.plan, seed, 0); });
    return adaptive_krnr_paper(ctx, x0_mod, eps_mod, nc.abar, k, delta);
  }
  for (int round = 0; round < 3; ++round) {
    ops::run_now(ctx, [&](vk::Recorder& rec) { apply_slm(rec, x0_mod, eps_mod, nc.plan, seed, round); });
    eps_mod = adaptive_krnr_official(ctx, x0_mod, eps_mod, mu, sigma, nc.abar, int(k), int(delta), 1);
  }
  return eps_mod;
}

// Host reference of the composition: SLM (the GPU op, checked bit for bit against Philox in test_slm.cpp)
// on host-held latents, then the K-RNR reference, round by round, each output the next ε.
std::vector<float> host_init_noise(vk::Context& ctx, const NoiseCase& nc, const InitNoiseOptions& o) {
  std::vector<float> x0 = nc.x0.to_f32(), eps = nc.eps.to_f32();
  const reference::LatentShape ls{nc.shape[0], nc.shape[1], nc.shape[2], nc.shape[3]};
  for (int round = 0; round < o.rounds; ++round) {
    const Tensor dx = Tensor::upload(ctx, HostTensor::from_f32(nc.shape, x0)),
                 de = Tensor::upload(ctx, HostTensor::from_f32(nc.shape, eps));
    ops::run_now(ctx, [&](vk::Recorder& rec) { apply_slm(rec, dx, de, nc.plan, o.seed, round); });
    x0 = dx.download(ctx).to_f32();
    eps = de.download(ctx).to_f32();
    eps = o.adain == InitNoiseOptions::Adain::per_channel
              ? reference::adaptive_krnr_paper(x0, eps, ls, nc.abar, o.k, o.delta)
              : reference::adaptive_krnr_official_round(x0, eps, nc.mu.to_f32(), nc.sigma.to_f32(), nc.abar, int(o.k),
                                                        int(o.delta));
  }
  return eps;
}

double max_abs_diff(const std::vector<float>& a, const std::vector<float>& b) {
  EXPECT_EQ(a.size(), b.size());
  double m = 0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::fabs(double(a[i]) - b[i]));
  return m;
}

TEST_F(GpuTest, InitNoisePresetsMatchPreviousInlineCodeAndHostReference) {
  const NoiseCase nc(ctx());
  const Tensor x0 = Tensor::upload(ctx(), nc.x0), eps = Tensor::upload(ctx(), nc.eps), mu = Tensor::upload(ctx(), nc.mu),
               sigma = Tensor::upload(ctx(), nc.sigma);
  for (bool official : {false, true}) {
    InitNoiseOptions o = official ? InitNoiseOptions::official() : InitNoiseOptions::paper();
    o.seed = 1234;
    EXPECT_EQ(o.rounds, official ? 3 : 1);
    EXPECT_EQ(o.delta, official ? 2 : 3);
    InitNoiseInputs in{&x0, &eps, &nc.plan, official ? &mu : nullptr, official ? &sigma : nullptr, nc.abar};
    const std::vector<float> got = init_noise(ctx(), in, o).download(ctx()).to_f32();
    const std::vector<float> before =
        previous_inline(ctx(), nc, official, x0, eps, mu, sigma, o.seed, o.k, o.delta).download(ctx()).to_f32();
    EXPECT_EQ(got, before) << (official ? "official" : "paper") << ": differs from the previous inline code";
    EXPECT_LT(max_abs_diff(got, host_init_noise(ctx(), nc, o)), 2e-5) << (official ? "official" : "paper");
    // The inputs are untouched.
    EXPECT_EQ(x0.download(ctx()).to_f32(), nc.x0.to_f32());
    EXPECT_EQ(eps.download(ctx()).to_f32(), nc.eps.to_f32());
    // Reproducible for a seed, different for another.
    EXPECT_EQ(init_noise(ctx(), in, o).download(ctx()).to_f32(), got);
    o.seed = 1235;
    EXPECT_NE(init_noise(ctx(), in, o).download(ctx()).to_f32(), got);
  }
}

TEST_F(GpuTest, InitNoiseMixedOptionsAndErrors) {
  const NoiseCase nc(ctx());
  const Tensor x0 = Tensor::upload(ctx(), nc.x0), eps = Tensor::upload(ctx(), nc.eps), mu = Tensor::upload(ctx(), nc.mu),
               sigma = Tensor::upload(ctx(), nc.sigma);
  // Mixed: the paper's per-channel AdaIN over the official three rounds with δ = 2, and no SLM at all.
  InitNoiseOptions o = InitNoiseOptions::paper();
  o.rounds = 3;
  o.delta = 2;
  o.k = 7.5;
  InitNoiseInputs in{&x0, &eps, &nc.plan, nullptr, nullptr, nc.abar};
  EXPECT_LT(max_abs_diff(init_noise(ctx(), in, o).download(ctx()).to_f32(), host_init_noise(ctx(), nc, o)), 2e-5);
  o.slm = false;
  o.rounds = 1;
  in.slm = nullptr;
  const reference::LatentShape ls{nc.shape[0], nc.shape[1], nc.shape[2], nc.shape[3]};
  EXPECT_LT(max_abs_diff(init_noise(ctx(), in, o).download(ctx()).to_f32(),
                         reference::adaptive_krnr_paper(nc.x0.to_f32(), nc.eps.to_f32(), ls, nc.abar, 7.5, 2)),
            2e-5);
  // Errors name the option (its field in the library).
  InitNoiseOptions off = InitNoiseOptions::official();
  off.k = 2.5;
  InitNoiseInputs oin{&x0, &eps, &nc.plan, &mu, &sigma, nc.abar};
  EXPECT_NE(error_of([&] { init_noise(ctx(), oin, off); }).find("RunOptions::k"), std::string::npos);
  off.k = 10;
  off.delta = 0;
  EXPECT_NE(error_of([&] { init_noise(ctx(), oin, off); }).find("RunOptions::delta"), std::string::npos);
  off.delta = 2;
  oin.mu = nullptr;
  EXPECT_NE(error_of([&] { init_noise(ctx(), oin, off); }).find("mean"), std::string::npos);
  o = InitNoiseOptions::paper();
  o.rounds = 0;
  EXPECT_NE(error_of([&] { init_noise(ctx(), in, o); }).find("rounds"), std::string::npos);
}

TEST_F(GpuTest, InitNoiseSlmChangesOnlyTargetsToSourceValues) {
  // SLM seen through the whole stage: with ᾱ = 1 and k = δ = 1, K-RNR gives ε^(1) = x0' (a = 1, b = 0) and
  // AdaIN of it onto itself, so x_init is the modulated x0 (up to rounding).
  const NoiseCase nc(ctx());
  std::vector<float> marked(size_t(nc.x0.numel()));
  for (size_t i = 0; i < marked.size(); ++i) marked[i] = float(i) + 0.25f;  // value names its element
  const Tensor x0 = Tensor::upload(ctx(), HostTensor::from_f32(nc.shape, marked));
  const Tensor eps = Tensor::upload(ctx(), nc.eps);
  InitNoiseOptions o = InitNoiseOptions::paper();
  o.k = 1;
  o.delta = 1;
  InitNoiseInputs in{&x0, &eps, &nc.plan, nullptr, nullptr, 1.0};
  const std::vector<float> out = init_noise(ctx(), in, o).download(ctx()).to_f32();
  const int64_t C = nc.shape[1], hw = nc.shape[2] * nc.shape[3];
  int changed = 0;
  for (size_t e = 0; e < out.size(); ++e) {
    const int64_t f = int64_t(e) / (C * hw), cell = f * hw + int64_t(e) % hw;
    const long src = std::lround(out[e] - 0.25f);
    ASSERT_NEAR(out[e], float(src) + 0.25f, 1e-3f * (1 + std::fabs(out[e])));
    const int64_t sf = src / (C * hw), scell = sf * hw + src % hw;
    if (!nc.x0_target[size_t(cell)]) {
      EXPECT_EQ(src, long(e)) << "a non-target element changed";
    } else {
      EXPECT_TRUE(nc.x0_source[size_t(scell)]) << "element " << e << " took a value from a non-source cell";
      changed += src != long(e);
    }
  }
  EXPECT_EQ(changed, nc.plan.x0.n_targets);
}

TEST_F(GpuTest, PositionsToReplaceBroadcastsTheX0TargetsOverChannels) {
  SlmMasks m;
  m.frames = 2;
  m.height = 3;
  m.width = 5;
  std::mt19937 rng(3);
  for (int i = 0; i < 30; ++i) m.x0_target.push_back(uint8_t(rng() % 2));
  const std::vector<float> p = positions_to_replace(ctx(), m, 3).download(ctx()).to_f32();
  ASSERT_EQ(p.size(), 90u);
  for (int f = 0; f < 2; ++f)
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 15; ++k) EXPECT_EQ(p[size_t((f * 3 + c) * 15 + k)], m.x0_target[size_t(f * 15 + k)] ? 1.0f : 0.0f);
}

}  // namespace
}  // namespace dvs::diffusion
