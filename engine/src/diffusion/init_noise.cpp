#include "diffusion/init_noise.hpp"

#include <cmath>
#include <string>

#include "io/option_names.hpp"
#include "diffusion/krnr.hpp"
#include "dvs/error.hpp"
#include "tensor/dispatch.hpp"

namespace dvs::diffusion {

InitNoiseOptions InitNoiseOptions::paper() { return {}; }

InitNoiseOptions InitNoiseOptions::official() {
  InitNoiseOptions o;
  o.rounds = 3;
  o.adain = Adain::per_element;
  o.delta = 2;  // hard-coded in the official adaptive_k_rnr
  return o;
}

namespace {

void check(const InitNoiseInputs& in, const InitNoiseOptions& o) {
  if (!in.x0 || !in.eps_inv) throw Error("internal: init_noise needs x0 and eps_inv");
  if (in.x0->numel() != in.eps_inv->numel())
    throw Error("internal: init_noise: x0 " + in.x0->describe() + " and eps_inv " + in.eps_inv->describe() + " differ");
  if (o.rounds < 1) throw Error("init_noise: rounds must be ≥ 1, got " + std::to_string(o.rounds));
  const std::string k = option_name("RunOptions::k"), delta = option_name("RunOptions::delta");
  if (!(o.k > 0)) throw Error(k + " must be > 0, got " + std::to_string(o.k), ErrorKind::invalid_argument);
  if (!(o.delta > 0)) throw Error(delta + " must be > 0, got " + std::to_string(o.delta), ErrorKind::invalid_argument);
  if (o.slm && !in.slm) throw Error("internal: init_noise with SLM needs the SLM plan");
  if (o.adain == InitNoiseOptions::Adain::per_element) {
    if (!in.mu || !in.sigma) throw Error("internal: the per-element AdaIN needs the posterior mean and std");
    if (o.k != std::floor(o.k) || o.delta != std::floor(o.delta))
      throw Error(k + " and " + delta + " must be integers with the official (per-element) K-RNR, got k = " +
                      std::to_string(o.k) + ", delta = " + std::to_string(o.delta),
                  ErrorKind::invalid_argument);
  }
}

Tensor copy_of(vk::Context& ctx, const Tensor& t, const char* name) {
  Tensor out = Tensor::empty(ctx, t.shape(), DType::f32, name);
  ops::run_now(ctx, [&](vk::Recorder& rec) { rec.copy(t.buffer(), out.buffer(), t.bytes()); });
  return out;
}

}  // namespace

Tensor init_noise(vk::Context& ctx, const InitNoiseInputs& in, const InitNoiseOptions& o) {
  check(in, o);
  // Private copies: SLM modulates in place.
  Tensor x0 = copy_of(ctx, *in.x0, "x0 (modulated)"), eps = copy_of(ctx, *in.eps_inv, "eps (modulated)");
  for (int round = 0; round < o.rounds; ++round) {
    if (o.slm) ops::run_now(ctx, [&](vk::Recorder& rec) { apply_slm(rec, x0, eps, *in.slm, o.seed, round); });
    eps = o.adain == InitNoiseOptions::Adain::per_channel
              ? adaptive_krnr_paper(ctx, x0, eps, in.alpha_cumprod_t0, o.k, o.delta)
              : adaptive_krnr_official(ctx, x0, eps, *in.mu, *in.sigma, in.alpha_cumprod_t0, int(o.k), int(o.delta), 1);
  }
  return eps;
}

}  // namespace dvs::diffusion
