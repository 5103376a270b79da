// RoPE split over token chunks: under binding=1KiB each batch's tokens go in chunks whose x/y windows start at
// an aligned row (odd sequence length and first token, so most chunks start unaligned); bitwise equal to the
// call under the limits in force before, with more dispatches.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "support/gpu.hpp"
#include "support/split_check.hpp"
#include "tensor/ops_position.hpp"

namespace dvs {
namespace {

class SplitPosition : public test::GpuTest {};

Tensor random_tensor(vk::Context& ctx, const Shape& s, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(-2.0f, 2.0f);
  std::vector<float> v(size_t(shape_numel(s)));
  for (float& x : v) x = d(rng);
  return Tensor::upload(ctx, HostTensor::from_f32(s, v));
}

TEST_F(SplitPosition, RopeSplitsOverTokenChunks) {
  struct Case {
    int64_t row_stride, col_offset, heads, head_dim;
  };
  // vec4 (head_dim 8) and pairs (head_dim 6, rows of 40 words: 160 bytes, aligned every other row).
  for (const Case c : {Case{48, 0, 2, 8}, Case{40, 2, 2, 6}}) {
    const int64_t B = 2, L = 37, first = 3, n = 31;
    const Tensor x = random_tensor(ctx(), {B * L, c.row_stride}, 1);
    const Tensor cos = random_tensor(ctx(), {n, c.head_dim}, 2), sin = random_tensor(ctx(), {n, c.head_dim}, 3);
    const HostTensor init = x.download(ctx());
    test::expect_split_equal(ctx(), "binding=1KiB,groups=64", {B * L, c.row_stride}, DType::f32,
                             [&](vk::Recorder& r, const Tensor& y) {
                               ops::rope(r, x, y, B, L, first, c.heads, c.head_dim, c.col_offset, cos, sin);
                             },
                             "rope head_dim " + std::to_string(c.head_dim), &init);
  }
}

}  // namespace
}  // namespace dvs
