#include "tensor/ops_resize.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

constexpr const char* kOp = "resize_bilinear";

void fail(const std::string& what) { throw Error(std::string("internal: ") + kOp + ": " + what); }

// The fp32 source-coordinate scale PyTorch derives from the sizes.
float source_scale(int64_t in, int64_t out, bool align_corners) {
  if (align_corners) return out > 1 ? float(in - 1) / float(out - 1) : 0.0f;
  return float(in) / float(out);
}

// Source rows [first, last] that output rows [r0, r1) of one plane read (the shader's rule, one row of slack).
std::pair<int64_t, int64_t> source_rows(int64_t r0, int64_t r1, int64_t in, float scale, bool align_corners) {
  auto src = [&](int64_t d) {
    float s = align_corners ? scale * float(d) : std::max(scale * (float(d) + 0.5f) - 0.5f, 0.0f);
    return int64_t(s);
  };
  return {std::max<int64_t>(src(r0) - 1, 0), std::min<int64_t>(src(r1 - 1) + 2, in - 1)};
}

}  // namespace

void resize_bilinear(vk::Recorder& rec, const Tensor& x, const Tensor& y, bool align_corners) {
  expect_dtype(kOp, "x", x, DType::f32);
  expect_dtype(kOp, "y", y, DType::f32);
  if (x.rank() < 2 || y.rank() != x.rank()) fail("x and y must be [..., H, W] of one rank: " + x.describe() + ", " + y.describe());
  for (size_t d = 0; d + 2 < x.rank(); ++d)
    if (x.dim(d) != y.dim(d)) fail("leading dims must match: " + x.describe() + " -> " + y.describe());
  const int64_t h = x.dim(x.rank() - 2), w = x.dim(x.rank() - 1), ho = y.dim(y.rank() - 2), wo = y.dim(y.rank() - 1);
  if (y.numel() == 0) return;
  if (h == 0 || w == 0) fail("empty input " + x.describe());
  if (x.numel() >= (int64_t(1) << 32) || y.numel() >= (int64_t(1) << 32)) fail("more than 2^32 elements");
  const int64_t planes = y.numel() / (ho * wo);
  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  struct {
    uint32_t h, w, ho, wo, first, n, x_base, y_base;
    float scale_h, scale_w;
    uint32_t align_corners;
  } pc{uint32_t(h), uint32_t(w), uint32_t(ho), uint32_t(wo), 0, 0, 0, 0, source_scale(h, ho, align_corners),
       source_scale(w, wo, align_corners), align_corners ? 1u : 0u};
  const vk::Pipeline& pipe = ctx.pipelines().get("nn/resize_bilinear");
  const uint64_t range = caps.max_storage_buffer_range, align = binding_alignment(caps);
  // One dispatch over output rows [row0, row1) of the flattened [planes·Ho] rows, binding only what they read.
  auto run = [&](int64_t row0, int64_t row1, bool whole) {
    const int64_t p0 = row0 / ho, p1 = (row1 - 1) / ho;
    const auto first_src = source_rows(row0 % ho, p0 == p1 ? (row1 - 1) % ho + 1 : ho, h, pc.scale_h, align_corners);
    const auto last_src = source_rows(p0 == p1 ? row0 % ho : 0, (row1 - 1) % ho + 1, h, pc.scale_h, align_corners);
    const uint64_t xs = uint64_t((p0 * h + first_src.first) * w), xe = uint64_t((p1 * h + last_src.second + 1) * w);
    pc.first = uint32_t(row0);
    pc.n = uint32_t(row1 - row0);
    vk::BufferView xv = whole ? x.buffer() : aligned_view(x.buffer(), xs * 4, xe * 4, align, 4, pc.x_base);
    vk::BufferView yv = whole ? y.buffer() : aligned_view(y.buffer(), uint64_t(row0 * wo) * 4, uint64_t(row1 * wo) * 4,
                                                          align, 4, pc.y_base);
    if (xv.size > range || yv.size > range) fail("internal chunking error: a view exceeds one binding");
    // Columns across x (64 per group), rows across y; both grid-stride within the group-count limits.
    const uint32_t gx = uint32_t(std::min<int64_t>(div_up(wo, 64), caps.max_workgroup_count[0]));
    const uint32_t gy = uint32_t(std::min<int64_t>(row1 - row0, caps.max_workgroup_count[1]));
    rec.dispatch(pipe, {xv, yv}, &pc, sizeof pc, gx, gy, 1, kOp);
  };
  if (uint64_t(x.bytes()) <= range && uint64_t(y.bytes()) <= range) return run(0, planes * ho, true);
  ctx.note_split(kOp);
  // Chunks of output rows whose input rows and output rows each fit one binding (with the alignment slack):
  // whole planes when a plane of each fits, else rows within a plane.
  const uint64_t room = range > 2 * align ? range - 2 * align : 0;
  const uint64_t in_plane = uint64_t(h * w) * 4, out_plane = uint64_t(ho * wo) * 4;
  if (in_plane <= room && out_plane <= room) {
    const int64_t per = int64_t(std::min(room / in_plane, room / out_plane));
    for_each_chunk(planes, per, [&](int64_t p, int64_t n) { run(p * ho, (p + n) * ho, false); });
    return;
  }
  // Input rows one output row reads at most: its span of the source plus the 1-row slack each side.
  const int64_t src_per_row = int64_t(std::ceil(double(h) / double(ho))) + 4;
  const int64_t rows = int64_t(std::min(room / (uint64_t(wo) * 4), room / (uint64_t(src_per_row) * uint64_t(w) * 4)));
  if (rows < 1) fail("one output row of " + y.describe() + " does not fit one binding");
  for (int64_t p = 0; p < planes; ++p)
    for_each_chunk(ho, rows, [&](int64_t r, int64_t n) { run(p * ho + r, p * ho + r + n, false); });
}

}  // namespace dvs::ops
