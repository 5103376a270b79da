#include "pipeline/denoise_stages.hpp"

#include <cstring>
#include <functional>

#include "diffusion/init_noise.hpp"

#include "dvs/error.hpp"
#include "pipeline/latent_layout.hpp"
#include "pipeline/transformer_denoiser.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs {

Tensor guidance_text(vk::Context& ctx, models::T5Encoder& t5, const T5Tokenizer& tokenizer, const std::string& negative,
                     const std::string& prompt, int text_len) {
  return guidance_text(ctx, t5.encode_prompts(tokenizer, {negative}, text_len), t5.encode_prompts(tokenizer, {prompt}, text_len));
}

Tensor guidance_text(vk::Context& ctx, const Tensor& uncond, const Tensor& cond) {
  const Shape& s = cond.shape();  // [1, L, D]
  if (s.size() != 3 || s[0] != 1 || uncond.shape() != s)
    throw Error("internal: guidance_text needs two [1, L, D] embeddings of the same shape");
  Tensor rows = Tensor::empty(ctx, {2, s[1], s[2]}, DType::f32, "guidance text");
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    rec.copy(uncond.buffer(), rows.rows(0, 1).buffer(), uncond.bytes());
    rec.copy(cond.buffer(), rows.rows(1, 1).buffer(), cond.bytes());
  });
  return rows;
}

HostTensor first_frame(const HostTensor& video) {
  const Shape& s = video.shape;  // [F, 3, H, W]: frame 0 is the first 3·H·W values
  HostTensor first({1, s[1], 1, s[2], s[3]}, DType::f32);
  std::memcpy(first.data.data(), video.data.data(), first.bytes());
  return first;
}

Tensor image_latent(vk::Context& ctx, const Tensor& frame0, int64_t latent_frames, float scaling) {
  const Tensor img0 = to_diffusion_layout(ctx, frame0, scaling);  // [1, C, h, w]
  const Shape& s = img0.shape();
  Tensor out = Tensor::zeros(ctx, {latent_frames, s[1], s[2], s[3]}, DType::f32, "image latent");
  ops::run_now(ctx, [&](vk::Recorder& rec) { rec.copy(img0.buffer(), out.buffer(), img0.bytes()); });
  return out;
}

std::vector<diffusion::StepCoefficients> inversion_steps(const Settings& st, const diffusion::CogVideoXSchedule& schedule,
                                                         int t0) {
  return st.official ? diffusion::inversion_steps_official(diffusion::DDIMInverseSchedule(schedule.config()), st.inversion_steps)
                     : diffusion::inversion_steps_paper(schedule, t0, st.inversion_steps);
}

Tensor initial_latent(vk::Context& ctx, const Settings& st, double k, uint64_t seed, const EncodedRender& enc,
                      const Tensor& eps_inv, const diffusion::SlmPlan* slm, double alpha_cumprod_t0) {
  diffusion::InitNoiseOptions noise = st.official ? diffusion::InitNoiseOptions::official() : diffusion::InitNoiseOptions::paper();
  noise.k = k;
  noise.delta = st.delta;
  noise.seed = seed;
  noise.slm = slm != nullptr;
  Tensor mu, sigma;  // the official per-element AdaIN's posterior statistics
  if (st.official) {
    mu = to_diffusion_layout(ctx, enc.posterior.mean, enc.scaling);
    sigma = to_diffusion_layout(ctx, enc.posterior.std, enc.scaling);
  }
  return diffusion::init_noise(
      ctx, {&enc.x0, &eps_inv, slm, st.official ? &mu : nullptr, st.official ? &sigma : nullptr, alpha_cumprod_t0}, noise);
}

Tensor invert_latent(vk::Context& ctx, models::CogVideoXTransformer& transformer,
                     const std::vector<diffusion::StepCoefficients>& steps, const Tensor& x0, const Tensor& image_latent,
                     const Tensor& text, const diffusion::LoopCallbacks& callbacks, ops::NonFiniteCheck* check) {
  TransformerDenoiser model(ctx, transformer, image_latent, text, 1);
  if (check) model.watch(check, "inversion");
  return diffusion::invert(ctx, x0, steps, std::ref(model), {false, 1.0}, callbacks);
}

diffusion::SampleResult sample_latent(vk::Context& ctx, models::CogVideoXTransformer& transformer,
                                      const diffusion::CogVideoXSchedule& schedule, const diffusion::SamplingPlan& plan,
                                      const Tensor& x_init, const Tensor& image_latent, const Tensor& text,
                                      const diffusion::Guidance& guidance, const diffusion::LoopCallbacks& callbacks,
                                      ops::NonFiniteCheck* check) {
  TransformerDenoiser model(ctx, transformer, image_latent, text, int(text.dim(0)));
  if (check) model.watch(check, "sampling");
  return diffusion::sample(ctx, x_init, schedule, plan, std::ref(model), guidance, callbacks);
}

}  // namespace dvs
