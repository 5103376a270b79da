#include "tensor/ops_vae_extra.hpp"

#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs::ops {

void vae_posterior(vk::Recorder& rec, const Tensor& moments, const Tensor& mean, const Tensor& std) {
  const char* op = "vae_posterior";
  expect_dtype(op, "moments", moments, DType::f32);
  expect_dtype(op, "mean", mean, DType::f32);
  expect_dtype(op, "std", std, DType::f32);
  if (moments.rank() < 2 || moments.dim(1) % 2 != 0)
    throw Error(std::string("internal: ") + op + ": moments " + moments.describe() + " must be [B, 2*Cl, ...]");
  Shape half = moments.shape();
  half[1] /= 2;
  expect_shape(op, "mean", mean, half);
  expect_shape(op, "std", std, half);
  const int64_t n = shape_numel(half);
  if (n == 0) return;
  if (moments.numel() >= int64_t(UINT32_MAX)) throw Error(std::string("internal: ") + op + ": tensor too large");
  struct {
    uint32_t n, half;
  } push{uint32_t(n), uint32_t(n / half[0])};
  const Grid g = grid_1d(rec.context().caps(), n, 64);
  rec.dispatch(rec.context().pipelines().get("nn/vae_posterior", {}), {moments.buffer(), mean.buffer(), std.buffer()},
               &push, sizeof push, g.x, g.y, g.z, op);
}

}  // namespace dvs::ops
