#include "tensor/ops_reduce.hpp"

#include <algorithm>
#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/kernel_tuning.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops {
namespace {

// Elements per first-level partial (one invocation each, a contiguous run: what CPU drivers load fastest):
// at least `min_chunk` (the device's DeviceTuning::reduce_min_chunk), grown so all segments together make
// at most ~1M partials (8 MiB of scratch); a multiple of 4 for the vec4 path.
int64_t chunk_for(int64_t min_chunk, int64_t segments, int64_t seg_len) {
  const int64_t total = segments * seg_len, max_partials = int64_t(1) << 20;
  int64_t chunk = std::max<int64_t>(min_chunk, (total + max_partials - 1) / max_partials);
  return (chunk + 3) / 4 * 4;
}

int64_t chunks_for(int64_t min_chunk, int64_t segments, int64_t seg_len) {
  const int64_t chunk = chunk_for(min_chunk, segments, seg_len);
  return std::max<int64_t>(1, (seg_len + chunk - 1) / chunk);
}

// The scratch sizes asked without a device (memory plans, groupnorm_scratch_elems) assume the smallest floor
// the tuning accepts (kernel_tuning.cpp's reduce_min_chunk range), so they bound every device's need.
constexpr int64_t kScratchMinChunk = 1024;

void check_f32(const char* op, const char* arg, const Tensor& t) { expect_dtype(op, arg, t, DType::f32); }

// Elements of x one dispatch may read through one binding: slack for the aligned-down start and the
// widening to whole vec4s.
int64_t window_room(const vk::DeviceCaps& caps) {
  return int64_t(binding_capacity(caps, 0) / 4) - int64_t(binding_alignment(caps) / 4) - 4;
}

// Most elements of x that `b` consecutive j of one segment can span.
int64_t block_extent(const Segments& segs, int64_t b) {
  if (segs.inner >= segs.seg_len) return b;
  return (segs.inner + b - 2) / segs.inner * segs.outer_stride + std::min(segs.inner, b);
}

// Contiguous segments whose blocks of `b` all start aligned: their windows need no slack.
bool aligned_blocks(const vk::DeviceCaps& caps, const Segments& segs, int64_t b) {
  const int64_t aw = int64_t(std::max<uint64_t>(16, binding_alignment(caps)) / 4);
  return segs.inner >= segs.seg_len && (segs.count == 1 || segs.seg_stride % aw == 0) && b % aw == 0;
}

int64_t room_for(const vk::DeviceCaps& caps, const Segments& segs, int64_t b) {
  return aligned_blocks(caps, segs, b) ? int64_t(binding_capacity(caps, 0) / 4) : window_room(caps);
}

// chunk_for(), shrunk where the limits in force cannot bind one block (bindings under 4 KiB, or unaligned
// ones of a few KiB; more partials then).
int64_t block_len_for(const vk::DeviceCaps& caps, const Segments& segs) {
  int64_t b = chunk_for(device_tuning(caps).reduce_min_chunk, segs.count, segs.seg_len);
  if (block_extent(segs, b) <= room_for(caps, segs, b)) return b;
  const int64_t room = window_room(caps);
  b = std::max<int64_t>(4, room / 4 * 4);
  while (b > 1 && block_extent(segs, b) > room) b = b > 4 ? b / 2 / 4 * 4 : b - 1;
  if (block_extent(segs, b) > room)
    throw Error("internal: reduce_segments: one element row of stride " + std::to_string(segs.outer_stride) +
                " does not fit one binding of " + std::to_string(binding_capacity(caps, 0)) + " bytes");
  return b;
}

int64_t blocks_for(const vk::DeviceCaps& caps, const Segments& segs) {
  const int64_t b = block_len_for(caps, segs);
  return std::max<int64_t>(1, (segs.seg_len + b - 1) / b);
}

}  // namespace

int64_t reduce_scratch_elems(int64_t segments, int64_t seg_len) {
  return segments * chunks_for(kScratchMinChunk, segments, seg_len) * 2;
}
int64_t reduce_scratch_elems(const Segments& segs) { return reduce_scratch_elems(segs.count, segs.seg_len); }
int64_t reduce_scratch_elems(const vk::DeviceCaps& caps, const Segments& segs) {
  return segs.count * blocks_for(caps, segs) * 2;
}

void reduce_segments(vk::Recorder& rec, const Tensor& x, const Segments& segs, ReduceMode mode, const Tensor& out0,
                     const Tensor& out1, const Tensor& scratch, int64_t out_offset) {
  const char* op = "reduce_segments";
  check_f32(op, "x", x);
  check_f32(op, "out0", out0);
  check_f32(op, "out1", out1);
  check_f32(op, "scratch", scratch);
  if (segs.count < 1 || segs.seg_len < 1 || segs.inner < 1)
    throw Error("internal: reduce_segments: bad segments (count " + std::to_string(segs.count) + ", length " +
                std::to_string(segs.seg_len) + ", inner " + std::to_string(segs.inner) + ")");
  // Largest element index touched must lie inside x.
  int64_t outer = (segs.seg_len + segs.inner - 1) / segs.inner;
  int64_t last = (segs.count - 1) * segs.seg_stride + (outer - 1) * segs.outer_stride +
                 std::min(segs.inner, segs.seg_len) - 1;
  if (last >= x.numel() || x.numel() > int64_t(UINT32_MAX))
    throw Error("internal: reduce_segments: segments reach element " + std::to_string(last) + " of " + x.describe());
  const vk::DeviceCaps& caps = rec.context().caps();
  if (scratch.numel() < reduce_scratch_elems(caps, segs))
    throw Error("internal: reduce_segments: scratch " + scratch.describe() + " smaller than " +
                std::to_string(reduce_scratch_elems(caps, segs)) + " elements");
  if (out0.numel() < out_offset + segs.count || (mode == ReduceMode::mean_var && out1.numel() < out_offset + segs.count))
    throw Error("internal: reduce_segments: outputs too small for " + std::to_string(segs.count) + " segments");

  const int64_t block_len = block_len_for(caps, segs), blocks = blocks_for(caps, segs);
  // vec4 loads when every run of 4 consecutive j is 4 consecutive, 16-byte aligned elements.
  const bool contiguous = segs.inner >= segs.seg_len;
  const bool vec4 = segs.seg_len % 4 == 0 && block_len % 4 == 0 && (segs.count == 1 || segs.seg_stride % 4 == 0) &&
                    (contiguous || (segs.inner % 4 == 0 && segs.outer_stride % 4 == 0));
  uint32_t spec1[] = {uint32_t(mode), vec4 ? 1u : 0u};
  uint32_t spec[] = {uint32_t(mode)};
  struct {
    uint32_t seg_len, inner, seg_stride, outer_stride, block_len, blocks, x_base, c_first, c_end, seg_first;
  } p1{uint32_t(segs.seg_len), uint32_t(std::min(segs.inner, segs.seg_len)), uint32_t(segs.seg_stride),
       uint32_t(segs.outer_stride), uint32_t(block_len), uint32_t(blocks), 0, 0, uint32_t(blocks), 0};
  vk::PipelineCache& pipes = rec.context().pipelines();
  const vk::Pipeline& partials = pipes.get("nn/reduce_partials", spec1);
  // Read as vec4s: views widened to whole 16-byte units (views are >= 16-byte aligned, padding is in-allocation).
  auto widen = [](vk::BufferView v) {
    v.size = (v.size + 15) / 16 * 16;
    return v;
  };
  const int64_t max_blocks = int64_t(caps.max_workgroup_count[0]) * 64;  // one invocation per block
  const int64_t max_segs = caps.max_workgroup_count[1];
  auto dispatch = [&](const vk::BufferView& xv, int64_t x_base, int64_t s0, int64_t ns, int64_t c0, int64_t nc) {
    p1.x_base = uint32_t(x_base);
    p1.seg_first = uint32_t(s0);
    p1.c_first = uint32_t(c0);
    p1.c_end = uint32_t(c0 + nc);
    rec.dispatch(partials, {xv, scratch.buffer()}, &p1, sizeof p1, div_up(nc, 64), uint32_t(ns), 1, "reduce_partials");
  };
  const vk::BufferView whole = widen(x.buffer());
  if (whole.size > binding_capacity(caps, 0) || segs.count > max_segs || blocks > max_blocks)
    rec.context().note_split("reduce");
  if (whole.size <= binding_capacity(caps, 0)) {
    for_each_chunk(segs.count, max_segs, [&](int64_t s0, int64_t ns) {
      for_each_chunk(blocks, max_blocks, [&](int64_t c0, int64_t nc) { dispatch(whole, 0, s0, ns, c0, nc); });
    });
  } else {
    // x larger than one binding: per segment, runs of blocks whose elements span one window each.
    const int64_t room = room_for(caps, segs, block_len);
    const int64_t align = int64_t(std::max<uint64_t>(16, binding_alignment(caps)) / 4);
    auto addr = [&](int64_t s, int64_t j) {
      return s * segs.seg_stride + j / segs.inner * segs.outer_stride + j % segs.inner;
    };
    auto span = [&](int64_t s, int64_t c0, int64_t nc) {
      return addr(s, std::min((c0 + nc) * block_len, segs.seg_len) - 1) + 1 - addr(s, c0 * block_len);
    };
    for (int64_t s = 0; s < segs.count; ++s) {
      for (int64_t c0 = 0; c0 < blocks;) {
        int64_t nc = 1;  // fits: block_len_for sized blocks for it
        while (c0 + nc < blocks && nc * 2 <= max_blocks && span(s, c0, std::min(nc * 2, blocks - c0)) <= room)
          nc = std::min(nc * 2, blocks - c0);
        for (int64_t step = nc / 2; step > 0; step /= 2)
          if (c0 + nc + step <= blocks && nc + step <= max_blocks && span(s, c0, nc + step) <= room) nc += step;
        const int64_t lo = addr(s, c0 * block_len), base = lo / align * align;
        const vk::BufferView xv =
            widen(x.buffer().sub(VkDeviceSize(base) * 4, VkDeviceSize(lo - base + span(s, c0, nc)) * 4));
        dispatch(xv, base, s, 1, c0, nc);
        c0 += nc;
      }
    }
  }
  struct {
    uint32_t seg_len, block_len, blocks, out_offset, segments;
  } p2{uint32_t(segs.seg_len), uint32_t(block_len), uint32_t(blocks), uint32_t(out_offset), uint32_t(segs.count)};
  const Grid g = grid_1d(caps, segs.count, 1);
  rec.dispatch(pipes.get("nn/reduce_merge", spec), {scratch.buffer(), out0.buffer(), out1.buffer()}, &p2, sizeof p2,
               g.x, g.y, 1, "reduce_merge");
}

Segments channel_segments(int64_t outer, int64_t channels, int64_t inner) {
  return Segments{channels, outer * inner, inner, inner, channels * inner};
}

void channel_mean_var(vk::Recorder& rec, const Tensor& x, int64_t outer, int64_t channels, int64_t inner,
                      const Tensor& mean, const Tensor& var, const Tensor& scratch) {
  if (outer * channels * inner != x.numel())
    throw Error("internal: channel_mean_var: " + x.describe() + " is not [" + std::to_string(outer) + ", " +
                std::to_string(channels) + ", " + std::to_string(inner) + "]");
  expect_shape("channel_mean_var", "mean", mean, {channels});
  expect_shape("channel_mean_var", "var", var, {channels});
  reduce_segments(rec, x, channel_segments(outer, channels, inner), ReduceMode::mean_var, mean, var, scratch);
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
