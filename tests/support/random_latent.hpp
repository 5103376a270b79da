// Seeded N(0, 1) host tensors for the diffusion tests, optionally with a per-element offset pattern
// (offset · (i mod 3)) so per-channel statistics differ.
#pragma once
#include <random>

#include "io/host_tensor.hpp"

namespace dvs::test {

inline HostTensor random_latent(Shape s, uint32_t seed, float offset = 0) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0, 1);
  HostTensor h(std::move(s), DType::f32);
  for (int64_t i = 0; i < h.numel(); ++i) h.as<float>()[i] = n(rng) + offset * float(i % 3);
  return h;
}

}  // namespace dvs::test
