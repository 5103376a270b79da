// Small ops only the CogVideoX VAE needs (kept apart from the shared kernel families).
#pragma once
#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops {

// DiagonalGaussianDistribution(moments): moments [B, 2*Cl, F, H, W] (f32) = concat(mean, logvar) on
// channels; mean = first Cl channels, std = exp(0.5 * clamp(logvar, -30, 20)). mean and std: [B, Cl, F, H, W].
void vae_posterior(vk::Recorder& rec, const Tensor& moments, const Tensor& mean, const Tensor& std);

}  // namespace dvs::ops
