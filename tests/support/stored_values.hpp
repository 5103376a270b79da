// Test operands in a storage dtype: a host tensor of `values` stored as f32, f16 or bf16 (round to nearest even),
// with `values` replaced by what the device will actually read, so a reference computed from them sees the same
// rounded operands.
#pragma once
#include <random>
#include <vector>

#include "io/host_tensor.hpp"
#include "tensor/tensor.hpp"

namespace dvs::test {

inline HostTensor stored_as(std::vector<float>& values, Shape shape, DType dt) {
  HostTensor h(std::move(shape), dt);
  for (size_t i = 0; i < values.size(); ++i) {
    if (dt == DType::f32) {
      h.as<float>()[i] = values[i];
    } else if (dt == DType::bf16) {
      h.as<uint16_t>()[i] = f32_to_bf16(values[i]);
      values[i] = bf16_to_f32(h.as<uint16_t>()[i]);
    } else {
      h.as<uint16_t>()[i] = f32_to_f16(values[i]);
      values[i] = f16_to_f32(h.as<uint16_t>()[i]);
    }
  }
  return h;
}

// A device tensor of uniform random values in [-scale, scale] (seeded), stored as `dt`.
inline Tensor random_stored(vk::Context& c, const Shape& s, uint32_t seed, float scale, DType dt) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(-scale, scale);
  std::vector<float> v(size_t(shape_numel(s)));
  for (float& e : v) e = d(rng);
  return Tensor::upload(c, stored_as(v, s, dt));
}

}  // namespace dvs::test
