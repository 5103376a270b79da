// Plain C++ (float64 arithmetic, float32 storage) reference of the K-RNR noise initialisation, for testing
// the GPU kernels. Latents are [F, C, H, W] row-major (a leading batch of 1 may be folded into F).
//
// With a = √ᾱ_t0 and b = √(1 − ᾱ_t0), k-th order Recursive Noise Re-injection is
//   ε^(0) = ε_inv,  ε^(j) = a·x0 + b·ε^(j−1)   ⇒   ε^(k) = m_k·x0 + n_k·ε_inv,
//   m_k = a·(1 − b^k)/(1 − b) (closed form, any real k > 0),  n_k = b^k.
// Paper preset: x_init = AdaIN(ε^(k), ε^(δ)) with per-channel statistics over (F, H, W) (δ = 3).
// Official preset (docs/design.md §6.6): per-element "analytic" AdaIN from the VAE posterior
// mean μ and std σ (both ×0.7), δ = 2, applied in 3 rounds, each feeding its output back as ε.
#pragma once
#include <cstdint>
#include <span>
#include <vector>

namespace dvs::diffusion::reference {

// ε^(k) = m·x0 + n·ε_inv
struct RnrCoefficients {
  double m = 0;
  double n = 1;
};

// Closed form for real k ≥ 0; b = 1 (ᾱ = 0 excluded: a = 0) uses the limit m = a·k.
RnrCoefficients krnr_closed_form(double alpha_cumprod, double k);
// The official k_coef: m = Σ_{i<k} a·b^i accumulated in order, n = b^k; integer k ≥ 0.
RnrCoefficients krnr_series(double alpha_cumprod, int k);

struct LatentShape {
  int64_t frames = 0, channels = 0, height = 0, width = 0;
  int64_t numel() const { return frames * channels * height * width; }
};

// out = m·x0 + n·eps elementwise (double arithmetic).
std::vector<float> combine(std::span<const float> x0, std::span<const float> eps, RnrCoefficients c);

// ε^(k) by the closed form, real k.
std::vector<float> krnr(std::span<const float> x0, std::span<const float> eps_inv, double alpha_cumprod, double k);
// ε^(k) by running the recursion k times per element (double accumulation), integer k ≥ 0.
std::vector<float> krnr_recursion(std::span<const float> x0, std::span<const float> eps_inv, double alpha_cumprod, int k);

// Per-channel AdaIN: for each channel c, statistics over (F, H, W) with the population variance;
// out = (content − μ_c)/√(var_c + eps)·√(var_s + eps) + μ_s.
std::vector<float> adain_per_channel(std::span<const float> content, std::span<const float> style, LatentShape shape,
                                     double eps = 1e-6);

// Paper preset: AdaIN(ε^(k), ε^(δ)) per channel (closed-form coefficients, real k and δ).
std::vector<float> adaptive_krnr_paper(std::span<const float> x0, std::span<const float> eps_inv, LatentShape shape,
                                       double alpha_cumprod, double k = 10, double delta = 3, double eps = 1e-6);

// One official round, as coded (series coefficients):
//   noisy = m_k·x0 + n_k·ε;  cur_mean = m_k·μ + n_k·ε;  cur_std = m_k·σ;
//   tgt_mean = m_δ·μ + n_δ·ε; tgt_std = m_δ·σ;  out = (noisy − cur_mean)/(cur_std + 1e-9)·tgt_std + tgt_mean.
std::vector<float> adaptive_krnr_official_round(std::span<const float> x0, std::span<const float> eps,
                                                std::span<const float> mu, std::span<const float> sigma,
                                                double alpha_cumprod, int k = 10, int delta = 2);
// `rounds` official rounds (3 in the official code), each output becoming the next ε. No SLM in between.
std::vector<float> adaptive_krnr_official(std::span<const float> x0, std::span<const float> eps_inv,
                                          std::span<const float> mu, std::span<const float> sigma,
                                          double alpha_cumprod, int k = 10, int delta = 2, int rounds = 3);

}  // namespace dvs::diffusion::reference
