// The noise initialisation stage (docs/design.md §5.5–5.6, §6.6): Stochastic Latent
// Modulation of x0 and ε_inv, then adaptive K-RNR, `rounds` times, each round's output the next ε:
//
//   for r in 0..rounds−1:   (x0, ε) ← SLM(x0, ε, round r) ;  ε ← K-RNR(x0, ε)
//   x_init = ε
//
// paper():    1 round, K-RNR with per-channel AdaIN(ε^(k), ε^(δ)), real k, δ = 3.
// official(): 3 rounds, the per-element analytic AdaIN from the VAE posterior μ, σ (×scaling), δ = 2.
// Every difference between the presets is a field, so they can be mixed. The inputs are never modified
// (x0's modulation is local to this call, as in the official code where it only feeds K-RNR).
#pragma once
#include <cstdint>

#include "diffusion/slm.hpp"
#include "tensor/tensor.hpp"
#include "vk/context.hpp"

namespace dvs::diffusion {

struct InitNoiseOptions {
  enum class Adain {
    per_channel,  // paper: statistics of ε^(k) and ε^(δ) per channel over (F, H, W)
    per_element,  // official: analytic, from the posterior mean and std (needs mu and sigma)
  };
  int rounds = 1;       // SLM + K-RNR rounds (paper 1, official 3)
  bool slm = true;      // false: K-RNR only (no plan needed)
  Adain adain = Adain::per_channel;
  double k = 10;        // K-RNR order (per_element: an integer ≥ 1)
  double delta = 3;     // AdaIN target order (paper 3, official 2; per_element: an integer ≥ 1)
  uint64_t seed = 42;   // SLM draws: Philox streams of this seed, one window per round

  static InitNoiseOptions paper();
  static InitNoiseOptions official();
};

struct InitNoiseInputs {
  const Tensor* x0 = nullptr;       // [F,C,H,W] f32 (official: a posterior sample)
  const Tensor* eps_inv = nullptr;  // [F,C,H,W] f32, the inverted latent at t0
  const SlmPlan* slm = nullptr;     // the index lists of the SLM masks (required when options.slm)
  const Tensor* mu = nullptr;       // per_element only: posterior mean and std, diffusion layout and scale
  const Tensor* sigma = nullptr;
  double alpha_cumprod_t0 = 0;      // ᾱ at t0 (the first strength-truncated timestep)
};

// Returns x_init, the latent at t0. Throws dvs::Error naming the option (--k, --delta, rounds) on a bad value,
// or naming the missing input.
Tensor init_noise(vk::Context& ctx, const InitNoiseInputs& in, const InitNoiseOptions& options);

}  // namespace dvs::diffusion
