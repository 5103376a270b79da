#include "pipeline/latent_layout.hpp"

#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_layout.hpp"
#include "tensor/ops_random.hpp"
#include "vk/context.hpp"

namespace dvs {

Tensor to_vae_layout(vk::Context& ctx, const Tensor& latent, float scale) {
  const Shape& s = latent.shape();
  Tensor scaled = Tensor::empty(ctx, s, DType::f32, "latent"), out = Tensor::empty(ctx, {1, s[1], s[0], s[2], s[3]}, DType::f32, "VAE latent");
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    ops::scale(rec, latent, scaled, scale);
    ops::permute(rec, scaled, out.reshape({s[1], s[0], s[2], s[3]}), {1, 0, 2, 3});
  });
  return out;
}

Tensor to_diffusion_layout(vk::Context& ctx, const Tensor& vae_latent, float scale) {
  const Shape& s = vae_latent.shape();  // [1, C, F, H, W]
  Tensor perm = Tensor::empty(ctx, {s[2], s[1], s[3], s[4]}, DType::f32, "latent"), out = Tensor::empty(ctx, perm.shape(), DType::f32, "latent");
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    ops::permute(rec, vae_latent.reshape({s[1], s[2], s[3], s[4]}), perm, {1, 0, 2, 3});
    ops::scale(rec, perm, out, scale);
  });
  return out;
}

Tensor video_to_device(vk::Context& ctx, const HostTensor& frames) {
  const Shape& s = frames.shape;
  Tensor in = Tensor::upload(ctx, frames), out = Tensor::empty(ctx, {1, s[1], s[0], s[2], s[3]}, DType::f32, "video");
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::permute(rec, in, out.reshape({s[1], s[0], s[2], s[3]}), {1, 0, 2, 3}); });
  return out;
}

HostTensor video_to_host(vk::Context& ctx, const Tensor& video) {
  const Shape& s = video.shape();  // [1,3,F,H,W]
  Tensor out = Tensor::empty(ctx, {s[2], s[1], s[3], s[4]}, DType::f32, "video");
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::permute(rec, video.reshape({s[1], s[2], s[3], s[4]}), out, {1, 0, 2, 3}); });
  return out.download(ctx);
}

Tensor posterior_sample(vk::Context& ctx, const models::VaePosterior& p, uint64_t seed, uint32_t stream) {
  Tensor noise = Tensor::empty(ctx, p.mean.shape(), DType::f32, "noise"), out = Tensor::empty(ctx, p.mean.shape(), DType::f32, "sample");
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    ops::random_normal(rec, noise, {seed, stream, 0});
    models::CogVideoXVae::sample(rec, p, noise, out);
  });
  return out;
}

}  // namespace dvs
