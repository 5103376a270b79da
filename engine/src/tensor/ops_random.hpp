// Counter-based random tensors (Philox4x32-10 in a shader). Element i of `out` is element (base + i) of the
// draw (seed, stream) as defined in tensor/philox.hpp, so a seed gives the same numbers on every device and
// run, whatever the tensor's shape, and a slice can be regenerated alone by passing its base.
#pragma once
#include <cstdint>

#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops {

struct RandomStream {
  uint64_t seed = 0;
  uint32_t stream = 0;  // independent sequence under one seed (e.g. one per use site)
  uint64_t base = 0;    // element index of out[0] within the draw
};

// f32 uniform in [lo, hi): lo + (hi - lo)·u with u = (word >> 8)·2^-24.
void random_uniform(vk::Recorder& rec, const Tensor& out, const RandomStream& s, float lo = 0.0f, float hi = 1.0f);
// f32 normal: mean + std·z, z by Box–Muller (see philox::normal).
void random_normal(vk::Recorder& rec, const Tensor& out, const RandomStream& s, float mean = 0.0f, float std = 1.0f);
// i32 uniform in [0, n), 1 ≤ n < 2^31, without modulo bias (see philox::below).
void random_below(vk::Recorder& rec, const Tensor& out, const RandomStream& s, uint32_t n);

}  // namespace dvs::ops
