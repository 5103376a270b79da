// The diffusion stages on the GPU against pack A's e2e case: K-RNR (official 3 rounds and the paper's
// per-channel AdaIN), the inversion loop and the guided sampling loop. The transformer is replaced by a
// denoiser that replays the model outputs the pack saved, so these tests check exactly the diffusion math
// (the model itself has its own golden tests). Tolerances: cases.json.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "diffusion/krnr.hpp"
#include "diffusion/sampler.hpp"
#include "io/npy.hpp"
#include "tensor/dispatch.hpp"
#include "support/files.hpp"
#include "support/gpu.hpp"

namespace dvs::diffusion {
namespace {

using test::GpuTest;

HostTensor load(const std::string& rel) { return read_npy(test::golden_path() / rel); }

const nlohmann::json& cases() {
  static const nlohmann::json j = nlohmann::json::parse(std::ifstream(test::golden_path() / "cases.json"));
  return j;
}
const nlohmann::json& settings() { return cases().at("e2e_settings"); }
std::pair<double, double> tolerance(const std::string& name) {
  for (const auto& c : cases().at("cases"))
    if (c.at("name") == name) return {c.at("tolerance").at("atol").get<double>(), c.at("tolerance").at("rtol").get<double>()};
  throw std::runtime_error("no case " + name);
}

void expect_close(const Tensor& ours, const HostTensor& golden, vk::Context& ctx, const std::string& case_name,
                  const std::string& what) {
  auto [atol, rtol] = tolerance(case_name);
  std::vector<float> a = ours.download(ctx).to_f32(), g = golden.to_f32();
  ASSERT_EQ(a.size(), g.size()) << what;
  double worst = 0;
  size_t bad = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    double d = std::fabs(double(a[i]) - g[i]);
    worst = std::max(worst, d);
    if (!(d <= atol + rtol * std::fabs(g[i]))) ++bad;
  }
  std::printf("  %-40s max |diff| = %.3e\n", what.c_str(), worst);
  EXPECT_EQ(bad, 0u) << what << ": max |diff| " << worst;
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
  Tensor mu = Tensor::upload(ctx(), vae_to_latent_layout(load("e2e/video_posterior_mean.npy"), 0.7f)).reshape(x0.shape());
  Tensor sigma = Tensor::upload(ctx(), vae_to_latent_layout(load("e2e/video_posterior_std.npy"), 0.7f)).reshape(x0.shape());
  const int k = settings().at("k_order"), delta = settings().at("delta_official"), rounds = settings().at("krnr_rounds");
  Tensor out = adaptive_krnr_official(ctx(), x0, eps, mu, sigma, s.alpha_cumprod(t0), k, delta, rounds);
  expect_close(out, load("e2e/x_init.npy"), ctx(), "e2e_krnr", "x_init (official, 3 rounds)");
  // Round by round from the golden inputs.
  Tensor round_out = Tensor::empty(ctx(), x0.shape(), DType::f32);
  const auto ck = reference::krnr_series(s.alpha_cumprod(t0), k), cd = reference::krnr_series(s.alpha_cumprod(t0), delta);
  for (int r = 0; r < rounds; ++r) {
    Tensor in = r == 0 ? eps : Tensor::upload(ctx(), load("e2e/krnr_round" + std::to_string(r - 1) + "_out.npy"));
    ops::run_now(ctx(), [&](vk::Recorder& rec) { krnr_official_round(rec, x0, in, mu, sigma, ck, cd, round_out); });
    expect_close(round_out, load("e2e/krnr_round" + std::to_string(r) + "_out.npy"), ctx(), "e2e_krnr",
                 "round " + std::to_string(r));
  }
}

TEST_F(GpuTest, GoldenKrnrPaperPerChannelAdain) {
  CogVideoXSchedule s(pack_scheduler());
  const int t0 = s.plan(settings().at("num_inference_steps"), settings().at("strength")).t0();
  Tensor x0 = Tensor::upload(ctx(), load("e2e/krnr_x0.npy"));
  Tensor eps = Tensor::upload(ctx(), load("e2e/eps_inv.npy"));
  Tensor out = adaptive_krnr_paper(ctx(), x0, eps, s.alpha_cumprod(t0), settings().at("k_order"), settings().at("delta_paper"));
  expect_close(out, load("e2e/brief_x_init.npy"), ctx(), "e2e_krnr_brief_variant", "x_init (paper, per-channel AdaIN)");
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
    expect_close(latents.at(int(ts[i])), load(name), ctx(), "e2e_inversion", name);
  }
  expect_close(eps, load("e2e/eps_inv.npy"), ctx(), "e2e_inversion", "eps_inv");
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
    expect_close(latents.at(int(ts[i])), load(name), ctx(), "e2e_sampling", name);
  }
  expect_close(r.latent, load("e2e/final_latent.npy"), ctx(), "e2e_sampling", "final_latent");
  std::string last = "e2e/sampling_step" + std::to_string(ts.size() - 1) + "_t" + std::to_string(int(ts.back())) + "_pred_x0.npy";
  expect_close(r.pred_x0, load(last), ctx(), "e2e_sampling", "last pred_x0");
}

}  // namespace
}  // namespace dvs::diffusion
