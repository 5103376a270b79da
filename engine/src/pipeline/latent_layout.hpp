// Moves between the pipeline's layouts on the device: diffusion latents [F,C,H,W], VAE latents and videos
// [1,C,F,H,W], and host videos [F,3,H,W].
#pragma once
#include <cstdint>

#include "io/host_tensor.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "tensor/tensor.hpp"

namespace dvs {

// [F,C,H,W] (diffusion) -> scale · [1,C,F,H,W] (VAE).
Tensor to_vae_layout(vk::Context& ctx, const Tensor& latent, float scale);
// [1,C,F,H,W] (VAE) -> scale · [F,C,H,W] (diffusion).
Tensor to_diffusion_layout(vk::Context& ctx, const Tensor& vae_latent, float scale);
// Video [F,3,H,W] on the host -> [1,3,F,H,W] on the device, and back.
Tensor video_to_device(vk::Context& ctx, const HostTensor& frames);
HostTensor video_to_host(vk::Context& ctx, const Tensor& video);
// x = mean + std·N(0,1) with Philox noise keyed by (seed, stream) (the official preset's posterior samples).
Tensor posterior_sample(vk::Context& ctx, const models::VaePosterior& p, uint64_t seed, uint32_t stream);

}  // namespace dvs
