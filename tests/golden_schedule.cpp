// Golden checks of the host diffusion math against the pack (DVS_GOLDEN_DIR): cases
// sched_cogvideox_tables, sched_cogvideox_step, sched_inverse_official, sched_inverse_positive_snr, the
// scheduler parts of e2e_inversion / e2e_sampling, e2e_krnr (official 3-round K-RNR) and
// e2e_krnr_brief_variant (paper per-channel AdaIN). Tolerances are the cases.json ones
// (|ours − golden| ≤ atol + rtol·|golden|); every test prints the max error it saw. Settings (step
// counts, strength, k, δ, rounds, guidance), the timestep lists and step files present, and the latent
// scaling factor come from cases.json and the pack's files, so any pack of this format can be run.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "diffusion/krnr_reference.hpp"
#include "diffusion/schedule.hpp"
#include "io/npy.hpp"
#include "support/gpu.hpp"
#include "support/pack.hpp"

namespace fs = std::filesystem;
using namespace dvs::diffusion;
namespace ref = dvs::diffusion::reference;

namespace {

fs::path pack() { return fs::path(dvs::test::golden_dir()); }

std::vector<float> load(const std::string& rel) { return dvs::read_npy(pack() / rel).to_f32(); }

dvs::HostTensor load_tensor(const std::string& rel) { return dvs::read_npy(pack() / rel); }

std::vector<int> load_ints(const std::string& rel) {
  std::vector<int> out;
  for (float v : load(rel)) out.push_back(int(v));
  return out;
}

// The pack's *_f64.npy: read_npy narrows '<f8' to float32, so parse the (version 1.0) file here.
std::vector<double> load_f64(const std::string& rel) {
  const fs::path path = pack() / rel;
  std::ifstream f(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  if (bytes.size() < 10 || bytes.compare(1, 5, "NUMPY") != 0) throw std::runtime_error(path.string() + ": not a .npy");
  const size_t header_len = uint8_t(bytes[8]) | (size_t(uint8_t(bytes[9])) << 8);
  const std::string header = bytes.substr(10, header_len);
  if (header.find("'<f8'") == std::string::npos) throw std::runtime_error(path.string() + ": not <f8");
  const size_t data = 10 + header_len, n = (bytes.size() - data) / 8;
  std::vector<double> out(n);
  std::memcpy(out.data(), bytes.data() + data, n * 8);
  return out;
}

using Tol = dvs::test::PackTolerance;
using dvs::test::pack_scaling;

const nlohmann::json& cases() { return dvs::test::pack_cases(); }
const nlohmann::json& case_of(const std::string& name) { return dvs::test::pack_case(name); }
Tol tol_of(const std::string& name) { return dvs::test::pack_tolerance(name); }

const nlohmann::json& e2e() { return cases().at("e2e_settings"); }

// The timesteps t of the files scheduler/<prefix>_t<t>_<suffix>.npy, ascending.
std::vector<int> step_files(const std::string& prefix, const std::string& suffix) {
  return dvs::test::pack_file_numbers("scheduler", prefix + "_t([0-9]+)_" + suffix + "\\.npy");
}

// The N of the files scheduler/<prefix>_timesteps_<N>.npy, ascending.
std::vector<int> timestep_files(const std::string& prefix) {
  return dvs::test::pack_file_numbers("scheduler", prefix + "_timesteps_([0-9]+)\\.npy");
}

// The set_timesteps(S) a scheduler case ran step() after: a "num_inference_steps" field when the case has
// one, else the S its description and call name ("... set_timesteps(50) ...").
int case_steps(const std::string& name) {
  const auto& c = case_of(name);
  if (c.contains("num_inference_steps")) return c.at("num_inference_steps").get<int>();
  const std::regex re("set_timesteps\\(([0-9]+)\\)");
  for (const char* key : {"description", "call"}) {
    std::smatch m;
    const std::string text = c.value(key, "");
    if (std::regex_search(text, m, re)) return std::stoi(m[1]);
  }
  throw std::runtime_error("cases.json: case " + name + " names no set_timesteps(S)");
}

// Max |a − g| and whether every element is within atol + rtol·|g|.
struct Compare {
  double max_abs = 0;
  size_t bad = 0;
  size_t first_bad = 0;
};

template <class A, class G>
Compare compare(const std::vector<A>& ours, const std::vector<G>& golden, Tol tol) {
  Compare c;
  EXPECT_EQ(ours.size(), golden.size());
  for (size_t i = 0; i < std::min(ours.size(), golden.size()); ++i) {
    const double d = std::fabs(double(ours[i]) - double(golden[i]));
    c.max_abs = std::max(c.max_abs, d);
    if (!(d <= tol.atol + tol.rtol * std::fabs(double(golden[i])))) {
      if (c.bad++ == 0) c.first_bad = i;
    }
  }
  return c;
}

#define EXPECT_CLOSE(ours, golden, tol, what)                                                                   \
  do {                                                                                                          \
    const Compare c_ = compare((ours), (golden), (tol));                                                        \
    std::printf("  %-48s max |diff| = %.3e\n", std::string(what).c_str(), c_.max_abs);                          \
    EXPECT_EQ(c_.bad, 0u) << (what) << ": " << c_.bad << " elements outside tolerance, first at " << c_.first_bad \
                          << ", max |diff| " << c_.max_abs;                                                     \
  } while (0)

// out = x·c.x + v·c.v with double arithmetic, rounded to float (what a GPU axpby computes).
std::vector<float> apply(const LinearCombination& c, const std::vector<float>& x, const std::vector<float>& v) {
  std::vector<float> out(x.size());
  for (size_t i = 0; i < x.size(); ++i) out[i] = float(c.x * double(x[i]) + c.v * double(v[i]));
  return out;
}

std::vector<float> cfg(const std::vector<float>& u, const std::vector<float>& c, double g) {
  std::vector<float> out(u.size());
  for (size_t i = 0; i < u.size(); ++i) out[i] = u[i] + float(g) * (c[i] - u[i]);
  return out;
}

// [1, C, F, H, W] → [F, C, H, W], times `scale`.
std::vector<float> bcfhw_to_fchw(const dvs::HostTensor& t, float scale) {
  const auto v = t.to_f32();
  const int64_t C = t.shape[1], F = t.shape[2], HW = t.shape[3] * t.shape[4];
  std::vector<float> out(v.size());
  for (int64_t c = 0; c < C; ++c)
    for (int64_t f = 0; f < F; ++f)
      for (int64_t p = 0; p < HW; ++p) out[size_t((f * C + c) * HW + p)] = scale * v[size_t((c * F + f) * HW + p)];
  return out;
}

SchedulerConfig pack_config() { return load_scheduler_config(pack() / "model"); }

}  // namespace

// ---------------------------------------------------------------------------------------------------------
// sched_cogvideox_tables

TEST(GoldenSchedule, CogVideoXTimesteps) {
  const CogVideoXSchedule s(pack_config());
  const std::vector<int> ns = timestep_files("cogvideox");
  ASSERT_FALSE(ns.empty());
  for (int n : ns) {
    const auto golden = load_ints("scheduler/cogvideox_timesteps_" + std::to_string(n) + ".npy");
    EXPECT_EQ(s.timesteps(n), golden) << "set_timesteps(" << n << ")";
  }
}

TEST(GoldenSchedule, CogVideoXAlphasCumprod) {
  const CogVideoXSchedule s(pack_config());
  EXPECT_CLOSE(s.alphas_cumprod(), load_f64("scheduler/cogvideox_alphas_cumprod_f64.npy"), (Tol{1e-12, 0}),
               "alphas_cumprod vs f64 file");
  EXPECT_CLOSE(s.alphas_cumprod(), load("scheduler/cogvideox_alphas_cumprod.npy"), tol_of("sched_cogvideox_tables"),
               "alphas_cumprod vs f32 file");
  EXPECT_EQ(s.alphas_cumprod().back(), 0.0) << "zero terminal SNR";
}

// ---------------------------------------------------------------------------------------------------------
// sched_cogvideox_step

TEST(GoldenSchedule, CogVideoXStep) {
  const CogVideoXSchedule s(pack_config());
  const auto v = load("scheduler/step_model_output.npy");
  const auto x = load("scheduler/step_sample.npy");
  const Tol tol = tol_of("sched_cogvideox_step");
  const std::vector<int> ts = step_files("cogvideox_step", "prev_sample");
  ASSERT_FALSE(ts.empty());
  const int S = case_steps("sched_cogvideox_step"), T = s.config().num_train_timesteps;
  for (int t : ts) {
    const StepCoefficients c = s.step(t, S);
    EXPECT_EQ(c.to_t, t - T / S < 0 ? -1 : t - T / S);
    const std::string stem = "scheduler/cogvideox_step_t" + std::to_string(t);
    EXPECT_CLOSE(apply(c.next, x, v), load(stem + "_prev_sample.npy"), tol, "step t=" + std::to_string(t) + " prev_sample");
    EXPECT_CLOSE(apply(c.pred_x0, x, v), load(stem + "_pred_x0.npy"), tol, "step t=" + std::to_string(t) + " pred_x0");
  }
}

// ---------------------------------------------------------------------------------------------------------
// sched_inverse_official / sched_inverse_positive_snr

namespace {

void check_inverse(const std::string& name, const SchedulerConfig& cfg) {
  const DDIMInverseSchedule s(cfg);
  const Tol kSchedTol = tol_of("sched_" + name);
  EXPECT_CLOSE(s.alphas_cumprod(), load("scheduler/" + name + "_alphas_cumprod.npy"), kSchedTol, name + " alphas_cumprod");
  const std::vector<int> ns = timestep_files(name);
  EXPECT_FALSE(ns.empty());
  for (int n : ns)
    EXPECT_EQ(s.timesteps(n), load_ints("scheduler/" + name + "_timesteps_" + std::to_string(n) + ".npy")) << name << " " << n;
  const auto v = load("scheduler/step_model_output.npy");
  const auto x = load("scheduler/step_sample.npy");
  const std::vector<int> ts = step_files(name + "_step", "next_sample");
  ASSERT_FALSE(ts.empty());
  const int S = case_steps("sched_" + name);
  for (int t : ts) {
    const StepCoefficients c = s.step(t, S);
    EXPECT_EQ(c.model_t, t);
    const std::string stem = "scheduler/" + name + "_step_t" + std::to_string(t);
    EXPECT_CLOSE(apply(c.next, x, v), load(stem + "_next_sample.npy"), kSchedTol, name + " t=" + std::to_string(t) + " next");
    EXPECT_CLOSE(apply(c.pred_x0, x, v), load(stem + "_pred_x0.npy"), kSchedTol, name + " t=" + std::to_string(t) + " pred_x0");
  }
}

}  // namespace

TEST(GoldenSchedule, InverseOfficial) {
  const SchedulerConfig cfg = pack_config();
  ASSERT_TRUE(cfg.rescale_betas_zero_snr);
  check_inverse("inverse_official", cfg);
  EXPECT_EQ(DDIMInverseSchedule(cfg).alphas_cumprod().back(), 0.0f);
}

TEST(GoldenSchedule, InversePositiveSnr) {
  SchedulerConfig cfg = pack_config();
  cfg.rescale_betas_zero_snr = false;
  check_inverse("inverse_positive_snr", cfg);
}

// ---------------------------------------------------------------------------------------------------------
// e2e_inversion / e2e_sampling: the scheduler arithmetic of each step from the pack's saved model outputs.

TEST(GoldenSchedule, E2eInversionSteps) {
  const DDIMInverseSchedule s(pack_config());
  const Tol kE2eTol = tol_of("e2e_inversion");
  const double g = e2e().at("guidance_scale").get<double>();
  const int n = e2e().at("num_inversion_steps").get<int>();
  const auto ts = s.timesteps(n);
  EXPECT_EQ(ts, load_ints("e2e/inversion_timesteps.npy"));
  std::vector<float> x = load("e2e/inversion_x0.npy");
  for (int i = 0; i < n; ++i) {
    const std::string stem = "e2e/inversion_step" + std::to_string(i) + "_t" + std::to_string(ts[size_t(i)]);
    const auto v = cfg(load(stem + "_model_uncond.npy"), load(stem + "_model_cond.npy"), g);
    x = apply(s.step(ts[size_t(i)], n).next, x, v);
    EXPECT_CLOSE(x, load(stem + "_latent.npy"), kE2eTol, stem + " (chained)");
  }
  EXPECT_CLOSE(x, load("e2e/eps_inv.npy"), kE2eTol, "eps_inv (chained)");
}

TEST(GoldenSchedule, E2eSamplingSteps) {
  const CogVideoXSchedule s(pack_config());
  const Tol kE2eTol = tol_of("e2e_sampling");
  const double g = e2e().at("guidance_scale").get<double>();
  const SamplingPlan plan = s.plan(e2e().at("num_inference_steps").get<int>(), e2e().at("strength").get<double>());
  EXPECT_EQ(plan.timesteps, load_ints("e2e/sampling_timesteps.npy"));
  std::vector<float> x = load("e2e/x_init.npy");
  for (int i = 0; i < plan.num_steps(); ++i) {
    const int t = plan.timesteps[size_t(i)];
    const std::string stem = "e2e/sampling_step" + std::to_string(i) + "_t" + std::to_string(t);
    const auto v = cfg(load(stem + "_model_uncond.npy"), load(stem + "_model_cond.npy"), g);
    EXPECT_CLOSE(v, load(stem + "_guided.npy"), kE2eTol, stem + " guided");
    const StepCoefficients c = s.step(t, plan.num_inference_steps);
    EXPECT_CLOSE(apply(c.pred_x0, x, v), load(stem + "_pred_x0.npy"), kE2eTol, stem + " pred_x0 (chained)");
    x = apply(c.next, x, v);
    EXPECT_CLOSE(x, load(stem + "_latent.npy"), kE2eTol, stem + " latent (chained)");
  }
  EXPECT_CLOSE(x, load("e2e/final_latent.npy"), kE2eTol, "final_latent (chained)");
}

// ---------------------------------------------------------------------------------------------------------
// e2e_krnr (official: per-element analytic AdaIN, k = 10, δ = 2, 3 rounds) and e2e_krnr_brief_variant

TEST(GoldenKrnr, OfficialThreeRounds) {
  const CogVideoXSchedule s(pack_config());
  const auto& rec = case_of("e2e_krnr");
  const Tol kE2eTol = tol_of("e2e_krnr");
  const int t0 = s.plan(e2e().at("num_inference_steps").get<int>(), e2e().at("strength").get<double>()).t0();
  ASSERT_EQ(t0, rec.at("t0").get<int>());
  const double abar = s.alpha_cumprod(t0);
  const int k = rec.at("k_order").get<int>(), delta = rec.at("delta").get<int>(), rounds = rec.at("rounds").get<int>();
  EXPECT_NEAR(abar, rec.at("abar_t0").get<double>(), 1e-15);
  const auto ck = ref::krnr_series(abar, k), cd = ref::krnr_series(abar, delta);
  EXPECT_NEAR(ck.m, rec.at("m_k").get<double>(), 1e-13);
  EXPECT_NEAR(ck.n, rec.at("n_k").get<double>(), 1e-13);
  EXPECT_NEAR(cd.m, rec.at("m_delta").get<double>(), 1e-13);
  EXPECT_NEAR(cd.n, rec.at("n_delta").get<double>(), 1e-13);

  const auto x0 = load("e2e/krnr_x0.npy");
  const auto mean_t = load_tensor("e2e/video_posterior_mean.npy");
  const auto std_t = load_tensor("e2e/video_posterior_std.npy");
  const auto mu = bcfhw_to_fchw(mean_t, pack_scaling()), sigma = bcfhw_to_fchw(std_t, pack_scaling());
  {  // x0 = scaling·(mean + std·noise): checks the layout conversion of μ and σ.
    const auto noise = bcfhw_to_fchw(load_tensor("e2e/video_sample_noise.npy"), 1.0f);
    std::vector<float> rebuilt(x0.size());
    for (size_t i = 0; i < x0.size(); ++i) rebuilt[i] = mu[i] + sigma[i] * noise[i];
    EXPECT_CLOSE(rebuilt, x0, kE2eTol, "krnr_x0 rebuilt from mean/std/noise");
  }
  std::vector<float> eps = load("e2e/eps_inv.npy");
  const std::vector<float> eps_inv = eps;
  for (int r = 0; r < rounds; ++r) {
    const std::string stem = "e2e/krnr_round" + std::to_string(r);
    EXPECT_CLOSE(ref::combine(x0, eps, ck), load(stem + "_eps_k.npy"), kE2eTol, stem + "_eps_k");
    EXPECT_CLOSE(ref::combine(x0, eps, cd), load(stem + "_eps_delta.npy"), kE2eTol, stem + "_eps_delta");
    eps = ref::adaptive_krnr_official_round(x0, eps, mu, sigma, abar, k, delta);
    EXPECT_CLOSE(eps, load(stem + "_out.npy"), kE2eTol, stem + "_out (chained)");
  }
  EXPECT_CLOSE(eps, load("e2e/x_init.npy"), kE2eTol, "x_init (chained)");
  EXPECT_CLOSE(ref::adaptive_krnr_official(x0, eps_inv, mu, sigma, abar, k, delta, rounds), load("e2e/x_init.npy"), kE2eTol,
               "x_init (adaptive_krnr_official)");
}

TEST(GoldenKrnr, PaperPerChannelAdain) {
  const CogVideoXSchedule s(pack_config());
  const auto& rec = case_of("e2e_krnr_brief_variant");
  const Tol kE2eTol = tol_of("e2e_krnr_brief_variant");
  const double abar =
      s.alpha_cumprod(s.plan(e2e().at("num_inference_steps").get<int>(), e2e().at("strength").get<double>()).t0());
  const double k = e2e().at("k_order").get<double>(), delta = e2e().at("delta_paper").get<double>();
  const dvs::HostTensor x0_t = load_tensor("e2e/krnr_x0.npy");
  const auto x0 = x0_t.to_f32();
  const auto eps_inv = load("e2e/eps_inv.npy");
  const auto ck = ref::krnr_closed_form(abar, k), cd = ref::krnr_closed_form(abar, delta);
  EXPECT_NEAR(ck.m, rec.at("c_k").get<double>(), 1e-13);
  EXPECT_NEAR(ck.n, rec.at("r_k").get<double>(), 1e-13);
  EXPECT_NEAR(cd.m, rec.at("c_delta").get<double>(), 1e-13);
  EXPECT_NEAR(cd.n, rec.at("r_delta").get<double>(), 1e-13);
  const auto eps_k = ref::krnr(x0, eps_inv, abar, k), eps_d = ref::krnr(x0, eps_inv, abar, delta);
  EXPECT_CLOSE(eps_k, load("e2e/brief_eps_k.npy"), kE2eTol, "brief_eps_k");
  EXPECT_CLOSE(eps_d, load("e2e/brief_eps_delta.npy"), kE2eTol, "brief_eps_delta");
  ASSERT_EQ(x0_t.shape.size(), 5u);  // B, F, C, H, W with B = 1 folded into F
  const ref::LatentShape shape{x0_t.shape[0] * x0_t.shape[1], x0_t.shape[2], x0_t.shape[3], x0_t.shape[4]};
  EXPECT_CLOSE(ref::adain_per_channel(eps_k, eps_d, shape), load("e2e/brief_x_init.npy"), kE2eTol, "brief_x_init");
  EXPECT_CLOSE(ref::adaptive_krnr_paper(x0, eps_inv, shape, abar, k, delta), load("e2e/brief_x_init.npy"), kE2eTol,
               "brief_x_init (adaptive_krnr_paper)");
}
