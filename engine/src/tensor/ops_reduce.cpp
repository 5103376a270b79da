#include "tensor/ops_reduce.hpp"

#include <algorithm>
#include <string>

#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops {
namespace {

// Elements per first-level partial (one invocation each, a contiguous run: what CPU drivers load fastest):
// 1024, grown so all segments together make at most ~1M partials (8 MiB of scratch); a multiple of 4 for
// the vec4 path.
int64_t chunk_for(int64_t segments, int64_t seg_len) {
  const int64_t total = segments * seg_len, max_partials = int64_t(1) << 20;
  int64_t chunk = std::max<int64_t>(1024, (total + max_partials - 1) / max_partials);
  return (chunk + 3) / 4 * 4;
}

int64_t chunks_for(int64_t segments, int64_t seg_len) {
  const int64_t chunk = chunk_for(segments, seg_len);
  return std::max<int64_t>(1, (seg_len + chunk - 1) / chunk);
}

void check_f32(const char* op, const char* arg, const Tensor& t) { expect_dtype(op, arg, t, DType::f32); }

}  // namespace

int64_t reduce_scratch_elems(int64_t segments, int64_t seg_len) {
  return segments * chunks_for(segments, seg_len) * 2;
}
int64_t reduce_scratch_elems(const Segments& segs) { return reduce_scratch_elems(segs.count, segs.seg_len); }

void reduce_segments(vk::Recorder& rec, const Tensor& x, const Segments& segs, ReduceMode mode, const Tensor& out0,
                     const Tensor& out1, const Tensor& scratch, int64_t out_offset) {
  const char* op = "reduce_segments";
  check_f32(op, "x", x);
  check_f32(op, "out0", out0);
  check_f32(op, "out1", out1);
  check_f32(op, "scratch", scratch);
  if (segs.count < 1 || segs.count > 65535 || segs.seg_len < 1 || segs.inner < 1)
    throw Error("internal: reduce_segments: bad segments (count " + std::to_string(segs.count) + ", length " +
                std::to_string(segs.seg_len) + ", inner " + std::to_string(segs.inner) + ")");
  // Largest element index touched must lie inside x.
  int64_t outer = (segs.seg_len + segs.inner - 1) / segs.inner;
  int64_t last = (segs.count - 1) * segs.seg_stride + (outer - 1) * segs.outer_stride +
                 std::min(segs.inner, segs.seg_len) - 1;
  if (last >= x.numel() || x.numel() > int64_t(UINT32_MAX))
    throw Error("internal: reduce_segments: segments reach element " + std::to_string(last) + " of " + x.describe());
  if (scratch.numel() < reduce_scratch_elems(segs))
    throw Error("internal: reduce_segments: scratch " + scratch.describe() + " smaller than " +
                std::to_string(reduce_scratch_elems(segs)) + " elements");
  if (out0.numel() < out_offset + segs.count || (mode == ReduceMode::mean_var && out1.numel() < out_offset + segs.count))
    throw Error("internal: reduce_segments: outputs too small for " + std::to_string(segs.count) + " segments");

  const int64_t block_len = chunk_for(segs.count, segs.seg_len), blocks = chunks_for(segs.count, segs.seg_len);
  // vec4 loads when every run of 4 consecutive j is 4 consecutive, 16-byte aligned elements.
  const bool contiguous = segs.inner >= segs.seg_len;
  const bool vec4 = segs.seg_len % 4 == 0 && block_len % 4 == 0 && (segs.count == 1 || segs.seg_stride % 4 == 0) &&
                    (contiguous || (segs.inner % 4 == 0 && segs.outer_stride % 4 == 0));
  uint32_t spec1[] = {uint32_t(mode), vec4 ? 1u : 0u};
  uint32_t spec[] = {uint32_t(mode)};
  struct {
    uint32_t seg_len, inner, seg_stride, outer_stride, block_len, blocks;
  } p1{uint32_t(segs.seg_len), uint32_t(std::min(segs.inner, segs.seg_len)), uint32_t(segs.seg_stride),
       uint32_t(segs.outer_stride), uint32_t(block_len), uint32_t(blocks)};
  if (div_up(blocks, 64) > 65535) throw Error("internal: reduce_segments: too many partials");
  vk::PipelineCache& pipes = rec.context().pipelines();
  vk::BufferView xv = x.buffer();
  xv.size = (xv.size + 15) / 16 * 16;  // read as vec4s; views are >= 64-byte aligned, padding is in-allocation
  rec.dispatch(pipes.get("nn/reduce_partials", spec1), {xv, scratch.buffer()}, &p1, sizeof p1,
               div_up(blocks, 64), uint32_t(segs.count), 1, "reduce_partials");
  struct {
    uint32_t seg_len, block_len, blocks, out_offset;
  } p2{uint32_t(segs.seg_len), uint32_t(block_len), uint32_t(blocks), uint32_t(out_offset)};
  rec.dispatch(pipes.get("nn/reduce_merge", spec), {scratch.buffer(), out0.buffer(), out1.buffer()}, &p2, sizeof p2,
               uint32_t(segs.count), 1, 1, "reduce_merge");
}

void channel_mean_var(vk::Recorder& rec, const Tensor& x, int64_t outer, int64_t channels, int64_t inner,
                      const Tensor& mean, const Tensor& var, const Tensor& scratch) {
  if (outer * channels * inner != x.numel())
    throw Error("internal: channel_mean_var: " + x.describe() + " is not [" + std::to_string(outer) + ", " +
                std::to_string(channels) + ", " + std::to_string(inner) + "]");
  expect_shape("channel_mean_var", "mean", mean, {channels});
  expect_shape("channel_mean_var", "var", var, {channels});
  Segments s{channels, outer * inner, inner, inner, channels * inner};
  reduce_segments(rec, x, s, ReduceMode::mean_var, mean, var, scratch);
}

void sum_all(vk::Recorder& rec, const Tensor& x, const Tensor& out, const Tensor& scratch) {
  expect_shape("sum_all", "out", out, {1});
  reduce_segments(rec, x, {1, x.numel(), x.numel(), 0, 0}, ReduceMode::sum, out, out, scratch);
}

void max_all(vk::Recorder& rec, const Tensor& x, const Tensor& out, const Tensor& scratch) {
  expect_shape("max_all", "out", out, {1});
  reduce_segments(rec, x, {1, x.numel(), x.numel(), 0, 0}, ReduceMode::max, out, out, scratch);
}

}  // namespace dvs::ops
