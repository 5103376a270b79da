// The pipeline's glue around the diffusion loops, each piece a function of explicit inputs so that `dvs run`,
// `dvs invert` and the golden end-to-end tests (tests/golden_pipeline_e2e.cpp) run the same code: the CFG text
// rows, the I2V image latent, the inversion steps of a preset, and the two loops bound to the transformer.
#pragma once
#include <string>
#include <vector>

#include "diffusion/sampler.hpp"
#include "diffusion/slm.hpp"
#include "diffusion/schedule.hpp"
#include "io/host_tensor.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/cogvideox/tokenizer.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/settings.hpp"
#include "tensor/ops_check.hpp"
#include "tensor/tensor.hpp"

namespace dvs {

// The text of a guided model call, [2, L, D]: row 0 = uncond (the negative prompt), row 1 = cond (the prompt),
// the order diffusion::sample's guidance u + g·(c − u) reads.
Tensor guidance_text(vk::Context& ctx, models::T5Encoder& t5, const T5Tokenizer& tokenizer, const std::string& negative,
                     const std::string& prompt, int text_len);
// The same from the two rows' embeddings ([1, L, D] each).
Tensor guidance_text(vk::Context& ctx, const Tensor& uncond, const Tensor& cond);

// Frame 0 of a host video [F, 3, H, W] as a one-frame VAE input [1, 3, 1, H, W].
HostTensor first_frame(const HostTensor& video);

// The CogVideoX I2V conditioning latent (diffusers' prepare_latents), diffusion layout [latent_frames, C, h, w]:
// scaling · frame0 (the VAE latent [1, C, 1, h, w] of the first frame alone: its posterior mean or a sample) in
// latent frame 0, zeros in the others.
Tensor image_latent(vk::Context& ctx, const Tensor& frame0, int64_t latent_frames, float scaling);

// The inversion levels of the settings' preset up to t0 (official: diffusers' DDIMInverseScheduler over the
// whole schedule; paper: the float64 schedule up to t0).
std::vector<diffusion::StepCoefficients> inversion_steps(const Settings& st, const diffusion::CogVideoXSchedule& schedule,
                                                         int t0);

// Stages 6–7: x_init, the latent at t0, from enc.x0 and ε_inv by the settings' preset (paper: one round of
// K-RNR with per-channel AdaIN; official: three rounds with the per-element AdaIN from enc.posterior), with SLM
// from `slm` first in each round (null: K-RNR only). k: --k; seed: the SLM draws.
Tensor initial_latent(vk::Context& ctx, const Settings& st, double k, uint64_t seed, const EncodedRender& enc,
                      const Tensor& eps_inv, const diffusion::SlmPlan* slm, double alpha_cumprod_t0);

// DDIM inversion of x0 (diffusion layout) with the transformer conditioned on `image_latent` and one text row
// (the "" prompt: no guidance, as the official CFG over two identical rows). Returns ε_inv.
Tensor invert_latent(vk::Context& ctx, models::CogVideoXTransformer& transformer,
                     const std::vector<diffusion::StepCoefficients>& steps, const Tensor& x0, const Tensor& image_latent,
                     const Tensor& text, const diffusion::LoopCallbacks& callbacks,
                     ops::NonFiniteCheck* check = nullptr);

// Guided DDIM sampling from x_init over the plan's timesteps, the transformer conditioned on `image_latent` and
// the rows of `text` (guidance_text). `check` (optional, for both loops): scans every model output for NaN/Inf.
diffusion::SampleResult sample_latent(vk::Context& ctx, models::CogVideoXTransformer& transformer,
                                      const diffusion::CogVideoXSchedule& schedule, const diffusion::SamplingPlan& plan,
                                      const Tensor& x_init, const Tensor& image_latent, const Tensor& text,
                                      const diffusion::Guidance& guidance, const diffusion::LoopCallbacks& callbacks,
                                      ops::NonFiniteCheck* check = nullptr);

}  // namespace dvs
