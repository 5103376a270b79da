// The diffusion stages on the GPU against the pack's e2e case (DVS_GOLDEN_DIR; any pack of this format):
// K-RNR (official 3 rounds and the paper's per-channel AdaIN), the inversion loop and the guided sampling
// loop, with constant CFG (the pack's own rule) and with the official position-wise dynamic CFG applied to
// the pack's raw uncond/cond outputs (reference: a plain C++ loop on the pack's ᾱ table). The transformer is
// replaced by a denoiser that replays the model outputs the pack saved, so these tests check exactly the
// diffusion math (the model itself has its own golden tests). Sizes, step counts, timesteps and the latent
// scaling factor come from the pack's files and cases.json. Tolerances: cases.json.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <random>

#include "diffusion/krnr.hpp"
#include "diffusion/sampler.hpp"
#include "io/npy.hpp"
#include "tensor/dispatch.hpp"
#include "support/files.hpp"
#include "support/golden_compare.hpp"
#include "support/gpu.hpp"
#include "support/precision_rule.hpp"
#include "support/pack.hpp"

namespace dvs::diffusion {
namespace {

using test::GpuTest;
using test::pack_scaling;

HostTensor load(const std::string& rel) { return test::pack_npy(rel); }
const nlohmann::json& settings() { return test::pack_cases().at("e2e_settings"); }

void expect_close(const Tensor& ours, const HostTensor& golden, vk::Context& ctx, const std::string& case_name,
                  const std::string& what) {
  const auto [atol, rtol] = test::pack_tolerance(case_name);
  test::expect_close(what, ours.download(ctx), golden, atol, rtol);
}

// Against the pack file `rel`: these loops replay the pack's saved model outputs, so no linear, attention or
// convolution makes the result and the fp32 tolerance judges it under every tuning (support/precision_rule.hpp;
// the bf16 run's error is printed beside dvs's all the same).
void expect_close(const Tensor& ours, const std::string& rel, vk::Context& ctx, const std::string& case_name,
                  const std::string& what) {
  const auto [atol, rtol] = test::pack_tolerance(case_name);
  test::expect_golden(what, ours.download(ctx), rel, atol, rtol, test::kNoKernelOps);
}

// [1, C, F, H, W] -> [F, C, H, W] (host), times `scale`.
HostTensor vae_to_latent_layout(const HostTensor& t, float scale) {
  const int64_t C = t.shape[1], F = t.shape[2], HW = t.shape[3] * t.shape[4];
  HostTensor out({F, C, t.shape[3], t.shape[4]}, DType::f32);
  std::vector<float> v = t.to_f32();
  for (int64_t c = 0; c < C; ++c)
    for (int64_t f = 0; f < F; ++f)
      for (int64_t i = 0; i < HW; ++i) out.as<float>()[(f * C + c) * HW + i] = scale * v[size_t((c * F + f) * HW + i)];
  return out;
}

SchedulerConfig pack_scheduler() { return load_scheduler_config(test::golden_path() / "model"); }

// A denoiser that writes the pack's saved (uncond, cond) outputs for the timestep it is asked for.
Denoiser replay(vk::Context& ctx, const std::string& prefix) {
  return [&ctx, prefix](vk::Recorder&, const Tensor&, int t, const Tensor& v) {
    for (const auto& e : std::filesystem::directory_iterator(test::golden_path() / "e2e")) {
      std::string name = e.path().filename().string();
      std::string tag = "_t" + std::to_string(t) + "_model_uncond.npy";
      if (name.rfind(prefix, 0) == 0 && name.size() > tag.size() && name.compare(name.size() - tag.size(), tag.size(), tag) == 0) {
        std::string stem = name.substr(0, name.size() - std::string("uncond.npy").size());
        v.rows(0, 1).write(ctx, read_npy(e.path()));
        v.rows(1, 1).write(ctx, read_npy(test::golden_path() / "e2e" / (stem + "cond.npy")));
        return;
      }
    }
    FAIL() << "the pack has no saved model output for " << prefix << " t=" << t;
  };
}

TEST_F(GpuTest, GoldenKrnrOfficialRounds) {
  CogVideoXSchedule s(pack_scheduler());
  const int t0 = s.plan(settings().at("num_inference_steps"), settings().at("strength")).t0();
  Tensor x0 = Tensor::upload(ctx(), load("e2e/krnr_x0.npy"));
  Tensor eps = Tensor::upload(ctx(), load("e2e/eps_inv.npy"));
  Tensor mu = Tensor::upload(ctx(), vae_to_latent_layout(load("e2e/video_posterior_mean.npy"), pack_scaling())).reshape(x0.shape());
  Tensor sigma = Tensor::upload(ctx(), vae_to_latent_layout(load("e2e/video_posterior_std.npy"), pack_scaling())).reshape(x0.shape());
  const int k = settings().at("k_order"), delta = settings().at("delta_official"), rounds = settings().at("krnr_rounds");
  Tensor out = adaptive_krnr_official(ctx(), x0, eps, mu, sigma, s.alpha_cumprod(t0), k, delta, rounds);
  expect_close(out, "e2e/x_init.npy", ctx(), "e2e_krnr", "x_init (official, 3 rounds)");
  // Round by round from the golden inputs.
  Tensor round_out = Tensor::empty(ctx(), x0.shape(), DType::f32);
  const auto ck = reference::krnr_series(s.alpha_cumprod(t0), k), cd = reference::krnr_series(s.alpha_cumprod(t0), delta);
  for (int r = 0; r < rounds; ++r) {
    Tensor in = r == 0 ? eps : Tensor::upload(ctx(), load("e2e/krnr_round" + std::to_string(r - 1) + "_out.npy"));
    ops::run_now(ctx(), [&](vk::Recorder& rec) { krnr_official_round(rec, x0, in, mu, sigma, ck, cd, round_out); });
    expect_close(round_out, "e2e/krnr_round" + std::to_string(r) + "_out.npy", ctx(), "e2e_krnr",
                 "round " + std::to_string(r));
  }
}

TEST_F(GpuTest, GoldenKrnrPaperPerChannelAdain) {
  CogVideoXSchedule s(pack_scheduler());
  const int t0 = s.plan(settings().at("num_inference_steps"), settings().at("strength")).t0();
  Tensor x0 = Tensor::upload(ctx(), load("e2e/krnr_x0.npy"));
  Tensor eps = Tensor::upload(ctx(), load("e2e/eps_inv.npy"));
  Tensor out = adaptive_krnr_paper(ctx(), x0, eps, s.alpha_cumprod(t0), settings().at("k_order"), settings().at("delta_paper"));
  expect_close(out, "e2e/brief_x_init.npy", ctx(), "e2e_krnr_brief_variant", "x_init (paper, per-channel AdaIN)");
}

TEST_F(GpuTest, GoldenInversionLoop) {
  DDIMInverseSchedule inv(pack_scheduler());
  const int S = settings().at("num_inversion_steps");
  auto steps = inversion_steps_official(inv, S);
  std::vector<float> ts = load("e2e/inversion_timesteps.npy").to_f32();
  ASSERT_EQ(steps.size(), ts.size());
  for (size_t i = 0; i < ts.size(); ++i) EXPECT_EQ(steps[i].to_t, int(ts[i]));
  Tensor x0 = Tensor::upload(ctx(), load("e2e/inversion_x0.npy"));
  std::map<int, Tensor> latents;
  LoopCallbacks cb;
  cb.latent = [&](int, int t, const Tensor& x) { latents[t] = Tensor::upload(ctx(), x.download(ctx())); };
  Tensor eps = invert(ctx(), x0, steps, replay(ctx(), "inversion_step"), {true, settings().at("guidance_scale")}, cb);
  for (size_t i = 0; i < ts.size(); ++i) {
    std::string name = "e2e/inversion_step" + std::to_string(i) + "_t" + std::to_string(int(ts[i])) + "_latent.npy";
    expect_close(latents.at(int(ts[i])), name, ctx(), "e2e_inversion", name);
  }
  expect_close(eps, "e2e/eps_inv.npy", ctx(), "e2e_inversion", "eps_inv");
}

TEST_F(GpuTest, GoldenSamplingLoop) {
  CogVideoXSchedule s(pack_scheduler());
  SamplingPlan plan = s.plan(settings().at("num_inference_steps"), settings().at("strength"));
  std::vector<float> ts = load("e2e/sampling_timesteps.npy").to_f32();
  ASSERT_EQ(plan.timesteps.size(), ts.size());
  Tensor x = Tensor::upload(ctx(), load("e2e/x_init.npy"));
  std::map<int, Tensor> latents;
  LoopCallbacks cb;
  int steps_seen = 0;
  cb.latent = [&](int, int t, const Tensor& l) { latents[t] = Tensor::upload(ctx(), l.download(ctx())); };
  cb.progress = [&](int step, int total, int) {
    EXPECT_EQ(total, int(ts.size()));
    steps_seen = step;
  };
  SampleResult r = sample(ctx(), x, s, plan, replay(ctx(), "sampling_step"), {true, settings().at("guidance_scale")}, cb);
  EXPECT_EQ(steps_seen, int(ts.size()));
  for (size_t i = 0; i < ts.size(); ++i) {
    std::string name = "e2e/sampling_step" + std::to_string(i) + "_t" + std::to_string(int(ts[i])) + "_latent.npy";
    expect_close(latents.at(int(ts[i])), name, ctx(), "e2e_sampling", name);
  }
  expect_close(r.latent, "e2e/final_latent.npy", ctx(), "e2e_sampling", "final_latent");
  std::string last = "e2e/sampling_step" + std::to_string(ts.size() - 1) + "_t" + std::to_string(int(ts.back())) + "_pred_x0.npy";
  expect_close(r.pred_x0, last, ctx(), "e2e_sampling", "last pred_x0");
}

// The official position-wise dynamic CFG (docs/design.md §6.7) on the pack's saved per-step
// uncond/cond outputs: GPU loop vs a plain C++ loop that applies the rule and CogVideoXDDIMScheduler.step
// (pack README conventions) with the pack's ᾱ table, chained from x_init. P: a seeded pattern of latent cells
// (the official V < 1 is constant over channels), preservation scale 1 (official config).
TEST_F(GpuTest, GoldenSamplingLoopDynamicCfg) {
  CogVideoXSchedule s(pack_scheduler());
  const SamplingPlan plan = s.plan(settings().at("num_inference_steps"), settings().at("strength"));
  std::vector<float> ts = load("e2e/sampling_timesteps.npy").to_f32();
  ASSERT_EQ(size_t(plan.num_steps()), ts.size());
  const HostTensor x_init = load("e2e/x_init.npy");
  const Shape& xs = x_init.shape;  // [1, F, C, H, W]
  ASSERT_EQ(xs.size(), 5u);
  const int64_t F = xs[1], C = xs[2], HW = xs[3] * xs[4];
  std::mt19937 rng(7);
  std::vector<float> cells(size_t(F * HW)), positions(size_t(x_init.numel()));
  for (float& c : cells) c = float(rng() % 2);
  for (int64_t f = 0; f < F; ++f)
    for (int64_t c = 0; c < C; ++c)
      for (int64_t k = 0; k < HW; ++k) positions[size_t((f * C + c) * HW + k)] = cells[size_t(f * HW + k)];

  const std::vector<float> abar = load("scheduler/cogvideox_alphas_cumprod.npy").to_f32();
  const auto sched_cfg = nlohmann::json::parse(std::ifstream(test::golden_path() / "model" / "scheduler" / "scheduler_config.json"));
  const int T = sched_cfg.value("num_train_timesteps", 1000), S = settings().at("num_inference_steps");
  const double g = settings().at("guidance_scale"), p = 1.0, N = double(ts.size());

  auto run = [&](const std::vector<float>& pos, double pres, const std::string& what) {
    // Host reference, in double.
    std::vector<double> x(x_init.numel()), pred(x.size());
    const std::vector<float> xi = x_init.to_f32();
    for (size_t i = 0; i < x.size(); ++i) x[i] = xi[i];
    std::vector<std::vector<double>> latents;
    for (size_t step = 0; step < ts.size(); ++step) {
      const int t = int(ts[step]), prev = t - T / S;
      const std::string stem = "e2e/sampling_step" + std::to_string(step) + "_t" + std::to_string(t) + "_model_";
      const std::vector<float> u = load(stem + "uncond.npy").to_f32(), c = load(stem + "cond.npy").to_f32();
      const double gd = g + 2 - (1 + g * (1 - std::cos(std::numbers::pi * std::pow((N - t) / N, 5.0))) / 2);
      const double at = abar[size_t(t)], ap = prev >= 0 ? abar[size_t(prev)] : 1.0;
      const double A = std::sqrt((1 - ap) / (1 - at)), B = std::sqrt(ap) - std::sqrt(at) * A;
      for (size_t i = 0; i < x.size(); ++i) {
        const double v = u[i] + (pos[i] != 0 ? gd : pres) * (double(c[i]) - u[i]);
        pred[i] = std::sqrt(at) * x[i] - std::sqrt(1 - at) * v;
        x[i] = A * x[i] + B * pred[i];
      }
      latents.push_back(x);
    }
    // GPU.
    Guidance guide{true, g};
    guide.mode = GuidanceMode::dynamic;
    guide.positions = Tensor::upload(ctx(), HostTensor::from_f32(x_init.shape, pos));
    guide.preservation_scale = pres;
    std::map<int, Tensor> got;
    LoopCallbacks cb;
    cb.latent = [&](int, int t, const Tensor& l) { got[t] = Tensor::upload(ctx(), l.download(ctx())); };
    SampleResult r = sample(ctx(), Tensor::upload(ctx(), x_init), s, plan, replay(ctx(), "sampling_step"), guide, cb);
    auto as_host = [&](const std::vector<double>& v) {
      std::vector<float> f(v.begin(), v.end());
      return HostTensor::from_f32(x_init.shape, f);
    };
    for (size_t step = 0; step < ts.size(); ++step)
      expect_close(got.at(int(ts[step])), as_host(latents[step]), ctx(), "e2e_sampling",
                   what + " latent after t=" + std::to_string(int(ts[step])));
    expect_close(r.pred_x0, as_host(pred), ctx(), "e2e_sampling", what + " last pred_x0");
  };
  run(positions, p, "dynamic CFG, random P, p=1:");
  run(std::vector<float>(positions.size(), 1.0f), p, "dynamic CFG, P everywhere:");
  // P empty and p = g is the constant rule: the pack's own latents.
  Guidance guide{true, g};
  guide.mode = GuidanceMode::dynamic;
  guide.positions = Tensor::zeros(ctx(), x_init.shape, DType::f32);
  guide.preservation_scale = g;
  SampleResult r = sample(ctx(), Tensor::upload(ctx(), x_init), s, plan, replay(ctx(), "sampling_step"), guide);
  expect_close(r.latent, "e2e/final_latent.npy", ctx(), "e2e_sampling", "dynamic mode, P empty, p=g: final_latent");
}

}  // namespace
}  // namespace dvs::diffusion
