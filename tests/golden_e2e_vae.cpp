// The VAE ends of the pack's end-to-end case, through the pipeline's own layout conversions
// (pipeline/latent_layout, pipeline/denoise_stages): the I2V image latent built from the first frame (posterior
// mean + std · the pack's saved noise, × scaling_factor, in latent frame 0 and zeros after; the whole production
// tensor is compared) and the decoded final video
// (vae.decode(final_latent / scaling_factor), not clamped). Sizes and tolerances come from the pack
// (DVS_GOLDEN_DIR; cases.json: e2e_image_latents atol/rtol, e2e_sampling frames_atol).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "io/npy.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "pipeline/denoise_stages.hpp"
#include "pipeline/latent_layout.hpp"
#include "support/files.hpp"
#include "support/golden_compare.hpp"
#include "support/gpu.hpp"
#include "support/precision_rule.hpp"
#include "support/pack.hpp"
#include "tensor/dispatch.hpp"

namespace dvs {
namespace {

using test::GpuTest;

HostTensor load(const std::string& rel) { return test::pack_npy(rel); }

// `ours` against the pack file `rel` by the precision rule for the VAE's convolutions (support/precision_rule.hpp).
void expect_close(const HostTensor& ours, const std::string& rel, double atol, double rtol, const std::string& what) {
  test::expect_golden(what, ours, rel, atol, rtol, test::kConvOps);
}

float scaling(const models::CogVideoXVae& vae) { return float(vae.config().scaling_factor); }

TEST_F(GpuTest, GoldenE2eImageLatentFromTheFirstFrame) {
  const auto tol = test::pack_tolerance("e2e_image_latents");
  const double atol = tol.atol, rtol = tol.rtol;
  models::CogVideoXVae vae(ctx(), test::golden_path() / "model" / "vae");
  HostTensor image = load("e2e/image.npy");  // [1, 3, H, W] -> one frame of [1, 3, 1, H, W]
  image.shape = {image.shape[0], image.shape[1], 1, image.shape[2], image.shape[3]};
  const models::VaePosterior post = vae.encode(Tensor::upload(ctx(), image));
  expect_close(post.mean.download(ctx()), "e2e/image_posterior_mean.npy", atol, rtol, "image posterior mean");
  expect_close(post.std.download(ctx()), "e2e/image_posterior_std.npy", atol, rtol, "image posterior std");

  // The pipeline's official-preset path: mean + std·noise (the pack's noise replaces the torch generator's draw),
  // then the production image latent (pipeline/denoise_stages: latent frame 0, zeros after), compared whole.
  const Tensor noise = Tensor::upload(ctx(), load("e2e/image_sample_noise.npy"));
  Tensor sample = Tensor::empty(ctx(), post.mean.shape(), DType::f32);
  ops::run_now(ctx(), [&](vk::Recorder& rec) { models::CogVideoXVae::sample(rec, post, noise, sample); });
  const HostTensor golden = load("e2e/image_latents.npy");  // [1, Fl, C, h, w]
  const HostTensor ours = image_latent(ctx(), sample, golden.shape.at(1), scaling(vae)).download(ctx());
  expect_close(ours, "e2e/image_latents.npy", atol, rtol, "image_latents");
}

TEST_F(GpuTest, GoldenE2eFinalFramesDecoded) {
  const double frames_atol = test::pack_case("e2e_sampling").at("tolerance").at("frames_atol");
  models::CogVideoXVae vae(ctx(), test::golden_path() / "model" / "vae");
  HostTensor latent = load("e2e/final_latent.npy");  // [1, Fl, C, h, w]
  latent.shape.erase(latent.shape.begin());
  const Tensor z = to_vae_layout(ctx(), Tensor::upload(ctx(), latent), 1.0f / scaling(vae));
  expect_close(vae.decode(z).download(ctx()), "e2e/final_frames.npy", frames_atol, 0, "final_frames");
}

}  // namespace
}  // namespace dvs
