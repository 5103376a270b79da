// Small helpers every op file uses to turn sizes into dispatches. Ops record into a vk::Recorder (a whole
// model call is one recording); run_now() records and submits at once for tests and one-off work.
#pragma once
#include <cstdint>
#include <functional>
#include <string>

#include "dvs/error.hpp"
#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops {

// Workgroup grid for `items` invocations of `local` threads each, split over x and y so that no
// dimension exceeds 65535 groups. Shaders recover the flat index with flat_index() from
// shaders/common/index.glsl.
struct Grid {
  uint32_t x = 1, y = 1, z = 1;
};
Grid grid_1d(int64_t items, uint32_t local);

inline uint32_t div_up(int64_t a, int64_t b) { return uint32_t((a + b - 1) / b); }

// Records with a fresh Recorder and submits immediately.
void run_now(vk::Context& ctx, const std::function<void(vk::Recorder&)>& record);

// Throws an internal error naming the op when a tensor has an unexpected shape or dtype.
void expect_shape(const char* op, const char* arg, const Tensor& t, const Shape& shape);
void expect_dtype(const char* op, const char* arg, const Tensor& t, DType dtype);

}  // namespace dvs::ops
