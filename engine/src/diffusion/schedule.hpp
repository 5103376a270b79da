// Diffusion schedules on the host, as diffusers computes them, reduced to the scalar coefficients a GPU
// axpby applies to whole latents.
//
// CogVideoXSchedule = diffusers' CogVideoXDDIMScheduler (float64 tables): betas = linspace(√β_start,
// √β_end, T)², ᾱ = cumprod(1 − β), SNR shift ᾱ ← ᾱ/(s + (1 − s)ᾱ) (s = snr_shift_scale), THEN, if
// rescale_betas_zero_snr, the zero-terminal-SNR rescale applied to ᾱ itself (Lin et al.):
// √ᾱ ← (√ᾱ − √ᾱ_{T−1})·√ᾱ_0/(√ᾱ_0 − √ᾱ_{T−1}). Its step() is DDIM with η = 0 from t to
// prev_t = t − T//S (not the next list entry); ᾱ_prev = final_alpha_cumprod (1 with set_alpha_to_one)
// when prev_t < 0.
//
// DDIMInverseSchedule = diffusers' DDIMInverseScheduler built from the same config, as the official
// inverse-DVS code builds it: float32 tables (betas = linspace(...) in float32, squared; the zero-SNR
// rescale on the BETAS, then ᾱ recomputed), snr_shift_scale ignored. Its step() maps a latent from the
// source level s = min(t − T//S, T−1) (ᾱ_s = 1 when s < 0 and set_alpha_to_one) to the target level t;
// the model output is the one evaluated at the target t.
//
// Every step is linear in (x, model_output): x_next = c_x·x + c_v·out and x̂0 = a·x + b·out.
#pragma once
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace dvs::diffusion {

enum class PredictionType { v_prediction, epsilon, sample };
enum class TimestepSpacing { trailing, leading, linspace };

// scheduler/scheduler_config.json. Defaults are CogVideoX-5B-I2V's.
struct SchedulerConfig {
  int num_train_timesteps = 1000;
  double beta_start = 0.00085;
  double beta_end = 0.012;
  std::string beta_schedule = "scaled_linear";  // the only schedule supported
  PredictionType prediction_type = PredictionType::v_prediction;
  TimestepSpacing timestep_spacing = TimestepSpacing::trailing;
  bool rescale_betas_zero_snr = true;
  bool set_alpha_to_one = true;
  int steps_offset = 0;
  double snr_shift_scale = 1.0;  // CogVideoXDDIMScheduler only (class default 3.0; the 5B config says 1.0)
};

// `path` is a model folder (reads scheduler/scheduler_config.json), a scheduler folder or the JSON file.
// Throws dvs::Error naming the file on a missing file, bad JSON or an unsupported setting.
SchedulerConfig load_scheduler_config(const std::filesystem::path& path);
SchedulerConfig parse_scheduler_config(std::string_view json_text, const std::string& source_name);

// out = x·x_in + v·model_output
struct LinearCombination {
  double x = 0;
  double v = 0;
};

// One DDIM (η = 0) transfer of a latent between two noise levels.
struct StepCoefficients {
  int from_t = 0;           // level of the input latent (-1: clean)
  int to_t = 0;             // level of the output latent (-1: clean)
  int model_t = 0;          // timestep the model output must have been evaluated at
  double alpha_from = 1;    // ᾱ at from_t
  double alpha_to = 1;      // ᾱ at to_t
  LinearCombination next;     // latent at to_t
  LinearCombination pred_x0;  // pred_original_sample
};

// Sampling timesteps after strength truncation (diffusers' get_timesteps):
// init = min(int(S·strength), S), t_start = max(S − init, 0), timesteps = all[t_start:].
struct SamplingPlan {
  int num_inference_steps = 0;  // S: what step() divides by (T//S), not the kept count
  std::vector<int> timesteps;   // kept timesteps, descending; timesteps.front() = t0
  int t0() const { return timesteps.front(); }
  int num_steps() const { return int(timesteps.size()); }
};

// DDIM transfer from level ᾱ_from to level ᾱ_to (η = 0) for a model output of the given type, in float64:
// x̂0 and ε̂ at the source level, then √ᾱ_to·x̂0 + √(1 − ᾱ_to)·ε̂. Throws on a singular case (epsilon with
// ᾱ_from = 0, sample with ᾱ_from = 1).
StepCoefficients ddim_transfer(double alpha_from, double alpha_to, PredictionType type);

class CogVideoXSchedule {
 public:
  explicit CogVideoXSchedule(const SchedulerConfig& config = {});

  const SchedulerConfig& config() const { return config_; }
  const std::vector<double>& alphas_cumprod() const { return alphas_cumprod_; }
  // ᾱ_t; t < 0 gives final_alpha_cumprod (1 with set_alpha_to_one, else ᾱ_0). Throws for t ≥ T.
  double alpha_cumprod(int t) const;
  double final_alpha_cumprod() const { return final_alpha_cumprod_; }

  // set_timesteps(S).timesteps: descending. Throws for S < 1 or S > T.
  std::vector<int> timesteps(int num_inference_steps) const;

  // Strength truncation. Throws dvs::Error when no step would run (int(S·strength) = 0) or strength is
  // outside (0, 1].
  SamplingPlan plan(int num_inference_steps, double strength) const;

  // step(model_output, t, x) after set_timesteps(S): from t to prev_t = t − T//S, model evaluated at t.
  StepCoefficients step(int t, int num_inference_steps) const;

  // Inversion transfer on this (float64) schedule from level s to level t (s < 0: clean, ᾱ = 1),
  // model_t = model_timestep (the paper preset evaluates the model at s, the official one at t).
  StepCoefficients inversion_step(int from_t, int to_t, int model_timestep) const;

  // Paper-preset inversion levels t_j = round(j·(t0 + 1)/S_inv) − 1, j = 1..S_inv (round half to even),
  // ascending, last = t0. Throws when S_inv < 1 or S_inv > t0 + 1.
  static std::vector<int> paper_inversion_timesteps(int t0, int num_inversion_steps);

 private:
  SchedulerConfig config_;
  std::vector<double> alphas_cumprod_;
  double final_alpha_cumprod_ = 1;
};

class DDIMInverseSchedule {
 public:
  explicit DDIMInverseSchedule(const SchedulerConfig& config = {});

  const SchedulerConfig& config() const { return config_; }
  const std::vector<float>& alphas_cumprod() const { return alphas_cumprod_; }  // float32, as the class
  float initial_alpha_cumprod() const { return initial_alpha_cumprod_; }

  // set_timesteps(S).timesteps: ascending. trailing and leading spacing.
  std::vector<int> timesteps(int num_inference_steps) const;

  // step(model_output, t, x) after set_timesteps(S): from s = min(t − T//S, T − 1) to t, model at t.
  // Square roots of the float32 ᾱ are taken in float32 as torch does; the coefficients are combined in
  // float64.
  StepCoefficients step(int t, int num_inference_steps) const;

 private:
  SchedulerConfig config_;
  std::vector<float> alphas_cumprod_;
  float initial_alpha_cumprod_ = 1;
};

// numpy's np.round(np.arange(T, 0, −T/S)) − 1 for the S trailing values, descending. (numpy's arange
// yields S + 1 values for some S, e.g. 61, the extra one being −1; only the first S are returned.)
std::vector<int> trailing_timesteps(int num_train_timesteps, int num_inference_steps);

}  // namespace dvs::diffusion
