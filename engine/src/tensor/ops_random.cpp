#include "tensor/ops_random.hpp"

#include <algorithm>
#include <bit>
#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

struct Push {
  uint32_t n, skew, n_blocks, first_block_lo, first_block_hi, seed_lo, seed_hi, stream;
  float a, b;
  uint32_t range;
};

void fill_range(vk::Recorder& rec, const char* op, const Tensor& out, const RandomStream& s, uint32_t dist, float a,
                float b, uint32_t range) {
  const int64_t n = out.numel();
  Push p{};
  p.n = uint32_t(n);
  p.skew = uint32_t(s.base % 4);
  p.n_blocks = uint32_t((p.skew + uint64_t(n) + 3) / 4);
  const uint64_t first_block = s.base / 4;
  p.first_block_lo = uint32_t(first_block);
  p.first_block_hi = uint32_t(first_block >> 32);
  p.seed_lo = uint32_t(s.seed);
  p.seed_hi = uint32_t(s.seed >> 32);
  p.stream = s.stream;
  p.a = a;
  p.b = b;
  p.range = range;
  const uint32_t spec[] = {dist};
  const vk::Pipeline& pipe = rec.context().pipelines().get("diffusion/philox_fill", spec);
  const uint32_t groups =
      std::clamp<uint32_t>(div_up(p.n_blocks, 64), 1, std::min(4096u, rec.context().caps().max_workgroup_count[0]));
  rec.dispatch(pipe, {out.buffer()}, &p, sizeof p, groups, 1, 1, op);
}

// Element ranges within one binding each; a range at element `first` draws from counter base + first, so the
// values are those of the unsplit fill.
void fill(vk::Recorder& rec, const char* op, const Tensor& out, const RandomStream& s, uint32_t dist, float a,
          float b, uint32_t range) {
  const int64_t n = out.numel();
  if (n == 0) return;
  if (n > int64_t(UINT32_MAX) - 4) throw Error(std::string("internal: ") + op + ": tensor " + out.describe() + " is too large");
  const int64_t chunk = rows_per_chunk(rec.context().caps(), op, {RowOperand{4, 0}}, n);
  if (chunk >= n) return fill_range(rec, op, out, s, dist, a, b, range);
  rec.context().note_split(op);
  for_each_chunk(n, chunk, [&](int64_t first, int64_t count) {
    const Tensor part =
        Tensor::on(out.buffer().sub(VkDeviceSize(first) * 4, VkDeviceSize(count) * 4), {count}, out.dtype());
    fill_range(rec, op, part, RandomStream{s.seed, s.stream, s.base + uint64_t(first)}, dist, a, b, range);
  });
}

}  // namespace

void random_uniform(vk::Recorder& rec, const Tensor& out, const RandomStream& s, float lo, float hi) {
  expect_dtype("random_uniform", "out", out, DType::f32);
  fill(rec, "random_uniform", out, s, 0, lo, hi, 0);
}

void random_normal(vk::Recorder& rec, const Tensor& out, const RandomStream& s, float mean, float std) {
  expect_dtype("random_normal", "out", out, DType::f32);
  fill(rec, "random_normal", out, s, 1, mean, std, 0);
}

void random_below(vk::Recorder& rec, const Tensor& out, const RandomStream& s, uint32_t n) {
  expect_dtype("random_below", "out", out, DType::i32);
  if (n == 0 || n > uint32_t(INT32_MAX))
    throw Error("internal: random_below: range [0, " + std::to_string(n) + ") must hold 1 to 2^31-1 values");
  fill(rec, "random_below", out, s, 2, 0, 0, n);
}

}  // namespace dvs::ops
