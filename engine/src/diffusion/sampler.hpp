// The two diffusion loops on the GPU: DDIM inversion of x0 up to t0 and guided DDIM sampling from t0
// (docs/design.md §5.4–5.7). Both take the model as a callback, so this folder never includes the models: the pipeline
// binds the transformer (with its image latent and text embeddings) into a Denoiser. Every step is
// v = model(x, τ), classifier-free guidance ĝ = u + g·(c − u), then x ← c_x·x + c_v·ĝ with the schedule's
// coefficients (schedule.hpp), all as axpby on whole latents.
#pragma once
#include <functional>
#include <vector>

#include "diffusion/schedule.hpp"
#include "dvs/error.hpp"
#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::diffusion {

// Records the model output for latent x (shape [F,C,H,W]) at `model_timestep` into v: [2,F,C,H,W] rows
// (uncond, cond) when guidance is on, else [1,F,C,H,W].
using Denoiser = std::function<void(vk::Recorder& rec, const Tensor& x, int model_timestep, const Tensor& v)>;

enum class GuidanceMode {
  constant,  // ĝ = u + g·(c − u) everywhere (paper, diffusers)
  dynamic,   // the official position-wise rule (docs/design.md §6.7), see below
};

struct Guidance {
  bool enabled = true;  // false: one model row, used as is
  double scale = 6.0;   // g
  // dynamic: ĝ = u + g_dyn(t)·(c − u) where `positions` ≠ 0 (P = the official latent mask V < 1, the
  // occluded cells) and u + preservation_scale·(c − u) elsewhere; g_dyn = dynamic_guidance_scale(g, t, N).
  GuidanceMode mode = GuidanceMode::constant;
  Tensor positions;                 // f32, the latent's shape
  double preservation_scale = 1.0;  // p (official config 1.0: the visible cells use the cond output)
};

// The official per-step scale, in double exactly as written (the argument of the cosine is ~1e8 for the raw
// timestep, so any other evaluation order changes the value): g + 2 − (1 + g·(1 − cos(π·((N − t)/N)^5))/2)
// with t the integer timestep and N the number of strength-truncated steps (docs/design.md §9, table C).
double dynamic_guidance_scale(double g, int t, int num_steps);

struct LoopCallbacks {
  std::function<void(int step, int total, int timestep)> progress;          // after each step
  std::function<bool()> cancelled;                                          // checked before each step
  std::function<void(int step, int timestep, const Tensor& latent)> latent;  // intermediates (optional)
};

class Cancelled : public Error {
 public:
  Cancelled() : Error("cancelled", ErrorKind::cancelled) {}
};

// Paper preset: levels t_j = round(j·(t0+1)/S_inv) − 1, from clean to t0, on the float64 schedule; the
// model sees the source level (DDIM-inversion approximation) or, with model_at_target, the target level.
std::vector<StepCoefficients> inversion_steps_paper(const CogVideoXSchedule& s, int t0, int num_steps,
                                                    bool model_at_target = false);
// Official preset: diffusers' DDIMInverseScheduler steps (float32 tables) for S steps, ascending, up to
// and including `up_to_t` (999 = the whole schedule, as the official code does).
std::vector<StepCoefficients> inversion_steps_official(const DDIMInverseSchedule& s, int num_steps, int up_to_t = 999);

// Runs the inversion steps from x0; returns the latent at the last level (ε_inv).
Tensor invert(vk::Context& ctx, const Tensor& x0, const std::vector<StepCoefficients>& steps, const Denoiser& model,
              const Guidance& guidance, const LoopCallbacks& callbacks = {});

struct SampleResult {
  Tensor latent;   // after the last step
  Tensor pred_x0;  // the last step's x̂0 (what is decoded)
};

// Guided DDIM sampling over plan.timesteps (CogVideoXDDIMScheduler.step semantics). Throws dvs::Error when the
// plan has no step or a dynamic guidance has no positions tensor of the latent's size.
SampleResult sample(vk::Context& ctx, const Tensor& x_init, const CogVideoXSchedule& s, const SamplingPlan& plan,
                    const Denoiser& model, const Guidance& guidance, const LoopCallbacks& callbacks = {});

}  // namespace dvs::diffusion
