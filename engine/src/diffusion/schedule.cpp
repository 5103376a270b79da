#include "diffusion/schedule.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>

#include "dvs/error.hpp"
#include "io/option_names.hpp"

namespace dvs::diffusion {

namespace fs = std::filesystem;

namespace {

[[noreturn]] void fail(const std::string& what) { throw Error("schedule: " + what); }

// torch.linspace on the CPU for a floating dtype, bit for bit as the x86-64 (AVX2) build computes it:
// step = (end − start)/(steps − 1) in that dtype; the first half counts up from start, the second half
// down from end (ATen linspace_kernel). Its vectorised loop fills two 256-bit vectors at a time: each
// vector's first element comes from the formula above, the others are base + j·step (Vectorized::arange),
// all with fused multiply-adds; the tail (< 2 vectors) takes the scalar formula. The pack's float32 and
// float64 tables match this exactly (a plain per-element formula is off by an ulp in ~half the entries).
template <class F>
std::vector<F> torch_linspace(F start, F end, int steps) {
  std::vector<F> out(static_cast<size_t>(steps));
  if (steps == 1) {
    out[0] = start;
    return out;
  }
  const F step = (end - start) / F(steps - 1);
  const int halfway = steps / 2;
  constexpr int lanes = int(32 / sizeof(F));
  int i = 0;
  for (; i <= steps - 2 * lanes; i += lanes) {
    const F base = i < halfway ? std::fma(step, F(i), start) : std::fma(-step, F(steps - i - 1), end);
    for (int j = 0; j < lanes; ++j) out[size_t(i + j)] = std::fma(F(j), step, base);
  }
  for (; i < steps; ++i) out[size_t(i)] = i < halfway ? F(start + step * F(i)) : F(end - step * F(steps - i - 1));
  return out;
}

// torch.cumprod on the CPU: accumulates in at::acc_type (double for float and double), each output
// rounded to the tensor's dtype.
template <class F>
std::vector<F> torch_cumprod(const std::vector<F>& v) {
  std::vector<F> out(v.size());
  double acc = 1;
  for (size_t i = 0; i < v.size(); ++i) {
    acc *= double(v[i]);
    out[i] = F(acc);
  }
  return out;
}

std::string read_text(const fs::path& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) fail("cannot open " + path.string());
  return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

void check_steps(int num_inference_steps, int T) {
  if (num_inference_steps < 1) fail("num_inference_steps must be >= 1 (got " + std::to_string(num_inference_steps) + ")");
  if (num_inference_steps > T)
    fail("num_inference_steps (" + std::to_string(num_inference_steps) + ") cannot exceed num_train_timesteps (" +
         std::to_string(T) + ")");
}

// x̂0 = p·x + q·out and ε̂ = r·x + s·out at a level with cumulative alpha `alpha`.
struct Decomposition {
  LinearCombination x0, eps;
};

Decomposition decompose(double alpha, PredictionType type) {
  const double sa = std::sqrt(alpha), sb = std::sqrt(1 - alpha);
  switch (type) {
    case PredictionType::v_prediction:
      return {{sa, -sb}, {sb, sa}};
    case PredictionType::epsilon:
      if (sa == 0) fail("epsilon prediction cannot recover x0 at a level with alpha_cumprod = 0");
      return {{1 / sa, -sb / sa}, {0, 1}};
    case PredictionType::sample:
      if (sb == 0) fail("sample prediction cannot recover the noise at a level with alpha_cumprod = 1");
      return {{0, 1}, {1 / sb, -sa / sb}};
  }
  fail("unknown prediction type");
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------
// config

SchedulerConfig parse_scheduler_config(std::string_view json_text, const std::string& source) {
  SchedulerConfig c;
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(json_text);
  } catch (const std::exception& e) {
    fail(source + " is not valid JSON: " + e.what());
  }
  if (!j.is_object()) fail(source + ": expected a JSON object");
  try {
    c.num_train_timesteps = j.value("num_train_timesteps", c.num_train_timesteps);
    c.beta_start = j.value("beta_start", c.beta_start);
    c.beta_end = j.value("beta_end", c.beta_end);
    c.beta_schedule = j.value("beta_schedule", c.beta_schedule);
    c.rescale_betas_zero_snr = j.value("rescale_betas_zero_snr", c.rescale_betas_zero_snr);
    c.set_alpha_to_one = j.value("set_alpha_to_one", c.set_alpha_to_one);
    c.steps_offset = j.value("steps_offset", c.steps_offset);
    if (j.contains("snr_shift_scale") && !j["snr_shift_scale"].is_null()) c.snr_shift_scale = j["snr_shift_scale"].get<double>();
    const std::string pred = j.value("prediction_type", std::string("v_prediction"));
    if (pred == "v_prediction") c.prediction_type = PredictionType::v_prediction;
    else if (pred == "epsilon") c.prediction_type = PredictionType::epsilon;
    else if (pred == "sample") c.prediction_type = PredictionType::sample;
    else fail(source + ": unsupported prediction_type '" + pred + "'");
    const std::string spacing = j.value("timestep_spacing", std::string("trailing"));
    if (spacing == "trailing") c.timestep_spacing = TimestepSpacing::trailing;
    else if (spacing == "leading") c.timestep_spacing = TimestepSpacing::leading;
    else if (spacing == "linspace") c.timestep_spacing = TimestepSpacing::linspace;
    else fail(source + ": unsupported timestep_spacing '" + spacing + "'");
    if (j.contains("trained_betas") && !j["trained_betas"].is_null()) fail(source + ": trained_betas is not supported");
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    fail(source + ": bad value: " + e.what());
  }
  if (c.beta_schedule != "scaled_linear") fail(source + ": unsupported beta_schedule '" + c.beta_schedule + "' (only scaled_linear)");
  if (c.num_train_timesteps < 2) fail(source + ": num_train_timesteps must be >= 2");
  if (!(c.beta_start > 0 && c.beta_end > 0 && c.beta_end < 1 && c.beta_start < 1))
    fail(source + ": beta_start and beta_end must lie in (0, 1)");
  if (!(c.snr_shift_scale > 0)) fail(source + ": snr_shift_scale must be > 0");
  return c;
}

SchedulerConfig load_scheduler_config(const fs::path& path) {
  fs::path file = path;
  if (path.extension() != ".json")  // a folder: the scheduler folder itself or a model folder
    file = fs::exists(path / "scheduler_config.json") ? path / "scheduler_config.json" : path / "scheduler" / "scheduler_config.json";
  if (!fs::exists(file)) fail(file.string() + " not found");
  return parse_scheduler_config(read_text(file), file.string());
}

// ---------------------------------------------------------------------------------------------------------
// timesteps

std::vector<int> trailing_timesteps(int T, int S) {
  check_steps(S, T);
  // np.arange(T, 0, -ratio) fills start + i·delta with delta = (start + step) − start.
  const double step = -double(T) / double(S);
  const double delta = (double(T) + step) - double(T);
  std::vector<int> ts(static_cast<size_t>(S));
  for (int i = 0; i < S; ++i) ts[size_t(i)] = int(std::nearbyint(double(T) + double(i) * delta)) - 1;
  return ts;
}

namespace {

std::vector<int> descending_timesteps(const SchedulerConfig& c, int S) {
  const int T = c.num_train_timesteps;
  check_steps(S, T);
  std::vector<int> ts(static_cast<size_t>(S));
  switch (c.timestep_spacing) {
    case TimestepSpacing::trailing:
      return trailing_timesteps(T, S);
    case TimestepSpacing::leading: {
      const int ratio = T / S;
      for (int i = 0; i < S; ++i) ts[size_t(i)] = (S - 1 - i) * ratio + c.steps_offset;
      return ts;
    }
    case TimestepSpacing::linspace: {
      // np.linspace(0, T − 1, S).round()[::-1]
      for (int i = 0; i < S; ++i) {
        const double v = S == 1 ? 0.0 : (i == S - 1 ? double(T - 1) : double(i) * (double(T - 1) / double(S - 1)));
        ts[size_t(S - 1 - i)] = int(std::nearbyint(v));
      }
      return ts;
    }
  }
  return ts;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------------
// generic DDIM transfer

StepCoefficients ddim_transfer(double alpha_from, double alpha_to, PredictionType type) {
  const Decomposition d = decompose(alpha_from, type);
  const double sa = std::sqrt(alpha_to), sb = std::sqrt(1 - alpha_to);
  StepCoefficients s;
  s.alpha_from = alpha_from;
  s.alpha_to = alpha_to;
  s.pred_x0 = d.x0;
  s.next = {sa * d.x0.x + sb * d.eps.x, sa * d.x0.v + sb * d.eps.v};
  return s;
}

// ---------------------------------------------------------------------------------------------------------
// CogVideoXDDIMScheduler

CogVideoXSchedule::CogVideoXSchedule(const SchedulerConfig& config) : config_(config) {
  const int T = config_.num_train_timesteps;
  std::vector<double> betas = torch_linspace<double>(std::sqrt(config_.beta_start), std::sqrt(config_.beta_end), T);
  for (double& b : betas) b = b * b;
  std::vector<double> alphas(static_cast<size_t>(T));
  for (int i = 0; i < T; ++i) alphas[size_t(i)] = 1.0 - betas[size_t(i)];
  alphas_cumprod_ = torch_cumprod(alphas);
  const double s = config_.snr_shift_scale;
  for (double& a : alphas_cumprod_) a = a / (s + (1 - s) * a);  // SNR shift (SD3); a no-op for s = 1
  if (config_.rescale_betas_zero_snr) {
    // Lin et al. Algorithm 1, applied to ᾱ (this class' variant): terminal √ᾱ moved to 0, first kept.
    std::vector<double> sq(alphas_cumprod_.size());
    for (size_t i = 0; i < sq.size(); ++i) sq[i] = std::sqrt(alphas_cumprod_[i]);
    const double s0 = sq.front(), sT = sq.back();
    const double scale = s0 / (s0 - sT);
    for (size_t i = 0; i < sq.size(); ++i) {
      const double v = (sq[i] - sT) * scale;
      alphas_cumprod_[i] = v * v;
    }
  }
  final_alpha_cumprod_ = config_.set_alpha_to_one ? 1.0 : alphas_cumprod_.front();
}

double CogVideoXSchedule::alpha_cumprod(int t) const {
  if (t < 0) return final_alpha_cumprod_;
  if (t >= config_.num_train_timesteps)
    fail("timestep " + std::to_string(t) + " is outside [0, " + std::to_string(config_.num_train_timesteps) + ")");
  return alphas_cumprod_[size_t(t)];
}

std::vector<int> CogVideoXSchedule::timesteps(int S) const { return descending_timesteps(config_, S); }

SamplingPlan CogVideoXSchedule::plan(int S, double strength) const {
  if (!(strength > 0.0 && strength <= 1.0))
    fail("strength must lie in (0, 1] (got " + std::to_string(strength) + ")");
  std::vector<int> all = timesteps(S);
  const int init = std::min(int(double(S) * strength), S);  // Python int(): truncation
  const int t_start = std::max(S - init, 0);
  if (init <= 0)
    fail("strength " + std::to_string(strength) + " with " + std::to_string(S) +
         " steps keeps no sampling step (int(steps*strength) = 0); raise " + option_name("RunOptions::strength") + " or " +
         option_name("RunOptions::steps"));
  SamplingPlan p;
  p.num_inference_steps = S;
  p.timesteps.assign(all.begin() + t_start, all.end());
  return p;
}

StepCoefficients CogVideoXSchedule::step(int t, int S) const {
  check_steps(S, config_.num_train_timesteps);
  if (t < 0 || t >= config_.num_train_timesteps) fail("step: timestep " + std::to_string(t) + " out of range");
  const int prev_t = t - config_.num_train_timesteps / S;
  const double at = alpha_cumprod(t);
  const double ap = alpha_cumprod(prev_t);  // final_alpha_cumprod below 0
  if (at >= 1.0) fail("step: alpha_cumprod(" + std::to_string(t) + ") = 1 leaves no noise to remove");
  const Decomposition d = decompose(at, config_.prediction_type);
  // The library's x0-form of DDIM (η = 0): x_prev = A·x + B·x̂0.
  const double A = std::sqrt((1 - ap) / (1 - at));
  const double B = std::sqrt(ap) - std::sqrt(at) * A;
  StepCoefficients s;
  s.from_t = t;
  s.to_t = prev_t < 0 ? -1 : prev_t;
  s.model_t = t;
  s.alpha_from = at;
  s.alpha_to = ap;
  s.pred_x0 = d.x0;
  s.next = {A + B * d.x0.x, B * d.x0.v};
  return s;
}

StepCoefficients CogVideoXSchedule::inversion_step(int from_t, int to_t, int model_timestep) const {
  if (to_t < 0 || to_t >= config_.num_train_timesteps) fail("inversion step: target level " + std::to_string(to_t) + " out of range");
  if (from_t >= to_t) fail("inversion step: source level " + std::to_string(from_t) + " must be below the target " + std::to_string(to_t));
  const double as = from_t < 0 ? 1.0 : alpha_cumprod(from_t);
  StepCoefficients s = ddim_transfer(as, alpha_cumprod(to_t), config_.prediction_type);
  s.from_t = from_t < 0 ? -1 : from_t;
  s.to_t = to_t;
  s.model_t = model_timestep;
  return s;
}

std::vector<int> CogVideoXSchedule::paper_inversion_timesteps(int t0, int n) {
  if (n < 1) fail("inversion steps must be >= 1 (got " + std::to_string(n) + ")");
  if (t0 < 0) fail("t0 must be >= 0 (got " + std::to_string(t0) + ")");
  if (n > t0 + 1)
    fail(std::to_string(n) + " inversion steps do not fit below t0 = " + std::to_string(t0) + " (at most t0 + 1)");
  std::vector<int> ts(static_cast<size_t>(n));
  for (int j = 1; j <= n; ++j) ts[size_t(j - 1)] = int(std::nearbyint(double(j) * double(t0 + 1) / double(n))) - 1;
  return ts;
}

// ---------------------------------------------------------------------------------------------------------
// DDIMInverseScheduler (float32 tables)

DDIMInverseSchedule::DDIMInverseSchedule(const SchedulerConfig& config) : config_(config) {
  const int T = config_.num_train_timesteps;
  // Python computes beta**0.5 in double; torch converts the endpoints to float32.
  std::vector<float> betas = torch_linspace<float>(float(std::sqrt(config_.beta_start)), float(std::sqrt(config_.beta_end)), T);
  for (float& b : betas) b = b * b;
  if (config_.rescale_betas_zero_snr) {
    // rescale_zero_terminal_snr(betas), every tensor op in float32.
    std::vector<float> alphas(betas.size());
    for (size_t i = 0; i < betas.size(); ++i) alphas[i] = 1.0f - betas[i];
    std::vector<float> sq = torch_cumprod(alphas);
    for (float& v : sq) v = std::sqrt(v);
    const float s0 = sq.front(), sT = sq.back();
    for (float& v : sq) v -= sT;
    const float scale = s0 / (s0 - sT);
    for (float& v : sq) v *= scale;
    std::vector<float> bar(sq.size());
    for (size_t i = 0; i < sq.size(); ++i) bar[i] = sq[i] * sq[i];
    alphas[0] = bar[0];
    for (size_t i = 1; i < bar.size(); ++i) alphas[i] = bar[i] / bar[i - 1];
    for (size_t i = 0; i < betas.size(); ++i) betas[i] = 1.0f - alphas[i];
  }
  std::vector<float> alphas(betas.size());
  for (size_t i = 0; i < betas.size(); ++i) alphas[i] = 1.0f - betas[i];
  alphas_cumprod_ = torch_cumprod(alphas);
  initial_alpha_cumprod_ = config_.set_alpha_to_one ? 1.0f : alphas_cumprod_.front();
}

std::vector<int> DDIMInverseSchedule::timesteps(int S) const {
  const int T = config_.num_train_timesteps;
  check_steps(S, T);
  std::vector<int> ts;
  if (config_.timestep_spacing == TimestepSpacing::trailing) {
    ts = trailing_timesteps(T, S);
    std::reverse(ts.begin(), ts.end());
  } else if (config_.timestep_spacing == TimestepSpacing::leading) {
    const int ratio = T / S;
    for (int i = 0; i < S; ++i) ts.push_back(i * ratio + config_.steps_offset);
  } else {
    fail("DDIMInverseScheduler supports leading and trailing timestep spacing only");
  }
  return ts;
}

StepCoefficients DDIMInverseSchedule::step(int t, int S) const {
  const int T = config_.num_train_timesteps;
  check_steps(S, T);
  if (t < 0 || t >= T) fail("inverse step: timestep " + std::to_string(t) + " out of range");
  const int s = std::min(t - T / S, T - 1);
  const float as = s >= 0 ? alphas_cumprod_[size_t(s)] : initial_alpha_cumprod_;
  const float at = alphas_cumprod_[size_t(t)];
  // (ᾱ)**0.5 and (1 − ᾱ)**0.5 of float32 tensors: float32 results (std::sqrt(float) rounds correctly).
  const double sas = std::sqrt(as), sbs = std::sqrt(1.0f - as);
  const double sat = std::sqrt(at), sbt = std::sqrt(1.0f - at);
  Decomposition d;
  if (config_.prediction_type == PredictionType::v_prediction) d = {{sas, -sbs}, {sbs, sas}};
  else d = decompose(as, config_.prediction_type);
  StepCoefficients st;
  st.from_t = s < 0 ? -1 : s;
  st.to_t = t;
  st.model_t = t;
  st.alpha_from = as;
  st.alpha_to = at;
  st.pred_x0 = d.x0;
  st.next = {sat * d.x0.x + sbt * d.eps.x, sat * d.x0.v + sbt * d.eps.v};
  return st;
}

}  // namespace dvs::diffusion
