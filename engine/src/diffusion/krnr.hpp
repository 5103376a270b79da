// K-order Recursive Noise Representation and its adaptive normalisation on the GPU (paper §4.2, docs/design.md §5.6;
// host reference in krnr_reference.hpp). Latents are [F, C, H, W] f32 (a batch of 1 folded into F).
//   ε^(k) = m_k·x0 + n_k·ε_inv  with (m_k, n_k) from reference::krnr_closed_form (real k) or krnr_series.
//   paper:    x_init = AdaIN(ε^(k), ε^(δ)), per-channel statistics over (F, H, W), δ = 3.
//   official: per-element analytic AdaIN from the posterior mean/std, δ = 2, applied `rounds` times.
#pragma once
#include "diffusion/krnr_reference.hpp"
#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::diffusion {

struct LatentDims {
  int64_t frames = 0, channels = 0, height = 0, width = 0;
  static LatentDims of(const Tensor& latent);  // [F,C,H,W] or [1,F,C,H,W]
};

// out = c.m·x0 + c.n·eps
void krnr_combine(vk::Recorder& rec, const Tensor& x0, const Tensor& eps, reference::RnrCoefficients c, const Tensor& out);

// Scratch for adain_per_channel: allocate once per latent size, reuse across calls.
struct AdainWorkspace {
  Tensor mean_x, var_x, mean_s, var_s, scratch;
  AdainWorkspace(vk::Context& ctx, const LatentDims& d);
};

// out = AdaIN(content, style) per channel; content, style, out [F,C,H,W] (out may alias content).
void adain_per_channel(vk::Recorder& rec, const Tensor& content, const Tensor& style, const Tensor& out,
                       const AdainWorkspace& ws, float eps = 1e-6f);

// One official round: out = analytic AdaIN of m_k·x0 + n_k·eps towards (m_δ, n_δ) with μ, σ per element.
void krnr_official_round(vk::Recorder& rec, const Tensor& x0, const Tensor& eps, const Tensor& mu, const Tensor& sigma,
                         reference::RnrCoefficients ck, reference::RnrCoefficients cd, const Tensor& out);

// Whole initialisations (record + submit), returning x_init.
Tensor adaptive_krnr_paper(vk::Context& ctx, const Tensor& x0, const Tensor& eps_inv, double alpha_cumprod_t0,
                           double k = 10, double delta = 3);
Tensor adaptive_krnr_official(vk::Context& ctx, const Tensor& x0, const Tensor& eps_inv, const Tensor& mu,
                              const Tensor& sigma, double alpha_cumprod_t0, int k = 10, int delta = 2, int rounds = 3);

}  // namespace dvs::diffusion
