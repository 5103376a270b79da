// The resampling ops of the VAE declared in tensor/ops_conv.hpp (temporal pair averaging, nearest resizes,
// the nearest x2 upsampling): plane-wise kernels split over planes and rows within the limits in force.
// (Split from ops_conv.cpp, which keeps the convolutions.)
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <string>

#include "dvs/error.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_conv.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

void expect(bool ok, const char* op, const std::string& what) {
  if (!ok) throw Error(std::string("internal: ") + op + ": " + what);
}

uint32_t u32(const char* op, int64_t v) {
  expect(v >= 0 && v <= int64_t(UINT32_MAX), op, "size " + std::to_string(v) + " out of range");
  return uint32_t(v);
}

// The limits a resampling op plans against (the ones in force: the device's, or lower under DVS_LIMITS).
struct ConvLimits {
  uint64_t storage = 0, align = 4, groups_x = 0, groups_y = 0, groups_z = 0;
};
ConvLimits conv_limits(const vk::DeviceCaps& caps) {
  ConvLimits l;
  l.storage = caps.max_storage_buffer_range;
  l.align = binding_alignment(caps);
  l.groups_x = caps.max_workgroup_count[0];
  l.groups_y = caps.max_workgroup_count[1];
  l.groups_z = caps.max_workgroup_count[2];
  return l;
}

// Walks a plane-wise op (grid: x columns, y rows, z planes) in dispatches of planes [z0, z0 + nz) x rows
// [r0, r0 + nr): every row of as many planes as fit, else one plane in as many rows as fit. fits(z0, nz, r0,
// nr) says whether a dispatch's views fit one binding; the grid stays within maxComputeWorkGroupCount.
// Notes a split of `op` (once) when it takes more than one dispatch.
template <class Fits, class Run>
void for_each_plane_chunk(vk::Context& ctx, const char* op, const ConvLimits& l, int64_t planes, int64_t rows,
                          Fits&& fits, Run&& run) {
  const int64_t max_z = int64_t(l.groups_z), max_y = int64_t(l.groups_y);
  bool noted = false;
  auto note = [&] {
    if (!noted) ctx.note_split(op);
    noted = true;
  };
  for (int64_t z0 = 0; z0 < planes;) {
    int64_t nz = std::min(planes - z0, max_z);
    while (nz > 1 && !(rows <= max_y && fits(z0, nz, int64_t(0), rows))) --nz;
    if (rows <= max_y && fits(z0, nz, int64_t(0), rows)) {
      if (nz < planes) note();
      run(z0, nz, int64_t(0), rows);
      z0 += nz;
      continue;
    }
    int64_t nr = std::min(rows, max_y);
    note();
    for (int64_t r0 = 0; r0 < rows; r0 += nr) {
      nr = std::min({nr, rows - r0, max_y});
      while (nr > 1 && !fits(z0, int64_t(1), r0, nr)) --nr;
      expect(fits(z0, int64_t(1), r0, nr), op, "one row exceeds one binding");
      run(z0, int64_t(1), r0, nr);
    }
    z0 += 1;
  }
}

}  // namespace

int64_t downsample_time_frames(int64_t frames) { return frames % 2 == 1 ? 1 + (frames - 1) / 2 : frames / 2; }

void avgpool_time_pairs(vk::Recorder& rec, const Tensor& x, const Tensor& y) {
  const char* op = "avgpool_time_pairs";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect(x.rank() == 5, op, "input must be [B, C, F, H, W], got " + x.describe());
  const int64_t f = x.dim(2), fo = downsample_time_frames(f), hw = x.dim(3) * x.dim(4), bc = x.dim(0) * x.dim(1);
  expect_shape(op, "y", y, {x.dim(0), x.dim(1), fo, x.dim(3), x.dim(4)});
  if (y.numel() == 0) return;
  const ConvLimits l = conv_limits(rec.context().caps());
  const bool vec4 = hw % 4 == 0;  // whole vec4s per plane (and 16-byte aligned planes)
  const int64_t unit = vec4 ? 4 : 1, align = int64_t(std::lcm<uint64_t>(l.align, uint64_t(unit) * 4));
  expect(uint64_t(div_up(hw / unit, 64)) <= l.groups_x, op, "plane too large: " + x.describe());
  const bool odd = f % 2 == 1;
  auto src_frame = [&](int64_t o) { return odd ? (o == 0 ? 0 : 2 * o - 1) : 2 * o; };  // first of the pair
  // Elements of x and y that planes (b*C + c) [z0, z0 + nz) x output frames [r0, r0 + nr) touch.
  auto spans = [&](int64_t z0, int64_t nz, int64_t r0, int64_t nr) {
    const int64_t o_last = r0 + nr - 1, last = odd && o_last == 0 ? 0 : src_frame(o_last) + 1;
    return std::array<uint64_t, 4>{uint64_t((z0 * f + src_frame(r0)) * hw), uint64_t(((z0 + nz - 1) * f + last + 1) * hw),
                                   uint64_t((z0 * fo + r0) * hw), uint64_t(((z0 + nz - 1) * fo + r0 + nr) * hw)};
  };
  const vk::Pipeline& pipe = rec.context().pipelines().get(vec4 ? "nn/avgpool_time_vec4" : "nn/avgpool_time");
  for_each_plane_chunk(rec.context(), op, l, bc, fo, [&](int64_t z0, int64_t nz, int64_t r0, int64_t nr) {
    auto s = spans(z0, nz, r0, nr);
    return (s[1] - s[0]) * 4 + uint64_t(align) <= l.storage && (s[3] - s[2]) * 4 + uint64_t(align) <= l.storage;
  }, [&](int64_t z0, int64_t nz, int64_t r0, int64_t nr) {
    auto s = spans(z0, nz, r0, nr);
    struct {
      uint32_t hw, frames, frames_out, bc_begin, fo_begin, x_base, y_base;
    } pc{u32(op, hw / unit), u32(op, f), u32(op, fo), u32(op, z0), u32(op, r0), 0, 0};
    const bool whole = uint64_t(x.bytes()) <= l.storage && uint64_t(y.bytes()) <= l.storage;
    vk::BufferView xv = whole ? x.buffer() : aligned_view(x.buffer(), s[0] * 4, s[1] * 4, uint64_t(align), uint32_t(unit * 4), pc.x_base);
    vk::BufferView yv = whole ? y.buffer() : aligned_view(y.buffer(), s[2] * 4, s[3] * 4, uint64_t(align), uint32_t(unit * 4), pc.y_base);
    rec.dispatch(pipe, {xv, yv}, &pc, sizeof pc, div_up(hw / unit, 64), uint32_t(nr), uint32_t(nz), op);
  });
}

void upsample_nearest(vk::Recorder& rec, const Tensor& x, const Tensor& y, bool keep_first_frame) {
  const char* op = "upsample_nearest";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect(x.rank() == 5 && y.rank() == 5, op, "x and y must be [B, C, F, H, W]: " + x.describe() + ", " + y.describe());
  expect(x.dim(0) == y.dim(0) && x.dim(1) == y.dim(1), op, "batch and channels must match: " + x.describe() + " -> " + y.describe());
  if (keep_first_frame)
    expect((x.dim(2) >= 2 && y.dim(2) >= 2) || x.dim(2) == y.dim(2), op,
           "keep_first_frame needs at least 2 frames on both sides: " + x.describe() + " -> " + y.describe());
  expect(y.numel() == 0 || x.numel() > 0, op, "empty input");
  struct {
    uint32_t frames, h, w, frames_out, ho, wo, keep_first, z_begin, row_begin, x_base, y_base;
  } pc{u32(op, x.dim(2)), u32(op, x.dim(3)), u32(op, x.dim(4)), u32(op, y.dim(2)), u32(op, y.dim(3)), u32(op, y.dim(4)),
       keep_first_frame && x.dim(2) != y.dim(2) ? 1u : 0u, 0, 0, 0, 0};
  if (y.numel() == 0) return;
  const ConvLimits l = conv_limits(rec.context().caps());
  expect(uint64_t(div_up(pc.wo, 64)) <= l.groups_x, op, "output too large: " + y.describe());
  const int64_t f = x.dim(2), h = x.dim(3), w = x.dim(4), fo = y.dim(2), ho = y.dim(3), wo = y.dim(4);
  // The shader's index rule in fp32 (PyTorch's), widened by a row / frame each way for safety in the spans.
  auto near = [](int64_t dst, int64_t n_in, int64_t n_out) {
    if (n_in == n_out) return dst;
    return std::min<int64_t>(int64_t(std::floor(float(dst) * (float(n_in) / float(n_out)))), n_in - 1);
  };
  auto src_plane = [&](int64_t z) {
    const int64_t o = z % fo, bcz = z / fo;
    const int64_t s = pc.keep_first ? (o == 0 ? 0 : 1 + near(o - 1, f - 1, fo - 1)) : near(o, f, fo);
    return bcz * f + s;
  };
  auto spans = [&](int64_t z0, int64_t nz, int64_t r0, int64_t nr) {
    const int64_t ra = std::max<int64_t>(near(r0, h, ho) - 1, 0), rb = std::min<int64_t>(near(r0 + nr - 1, h, ho) + 2, h);
    const bool all = r0 == 0 && nr == ho;
    return std::array<uint64_t, 4>{uint64_t(src_plane(z0) * h * w + (all ? 0 : ra * w)),
                                   uint64_t(src_plane(z0 + nz - 1) * h * w + (all ? h : rb) * w),
                                   uint64_t((z0 * ho + r0) * wo), uint64_t(((z0 + nz - 1) * ho + r0 + nr) * wo)};
  };
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/upsample_nearest");
  for_each_plane_chunk(rec.context(), op, l, y.dim(0) * y.dim(1) * fo, ho, [&](int64_t z0, int64_t nz, int64_t r0, int64_t nr) {
    auto s = spans(z0, nz, r0, nr);
    return (s[1] - s[0]) * 4 + l.align <= l.storage && (s[3] - s[2]) * 4 + l.align <= l.storage;
  }, [&](int64_t z0, int64_t nz, int64_t r0, int64_t nr) {
    auto s = spans(z0, nz, r0, nr);
    pc.z_begin = uint32_t(z0), pc.row_begin = uint32_t(r0);
    const bool whole = uint64_t(x.bytes()) <= l.storage && uint64_t(y.bytes()) <= l.storage;
    vk::BufferView xv = whole ? x.buffer() : aligned_view(x.buffer(), s[0] * 4, s[1] * 4, l.align, 4, pc.x_base);
    vk::BufferView yv = whole ? y.buffer() : aligned_view(y.buffer(), s[2] * 4, s[3] * 4, l.align, 4, pc.y_base);
    rec.dispatch(pipe, {xv, yv}, &pc, sizeof pc, div_up(pc.wo, 64), uint32_t(nr), uint32_t(nz), op);
  });
}

Shape upsample2x_shape(const Shape& x, bool compress_time) {
  expect(x.size() == 5, "upsample2x", "input must be [B, C, F, H, W], got [" + shape_str(x) + "]");
  int64_t f = x[2];
  int64_t fo = !compress_time || f <= 1 ? f : (f % 2 == 1 ? 1 + 2 * (f - 1) : 2 * f);
  return {x[0], x[1], fo, 2 * x[3], 2 * x[4]};
}

void upsample2x(vk::Recorder& rec, const Tensor& x, const Tensor& y, bool compress_time) {
  const char* op = "upsample2x";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect_shape(op, "y", y, upsample2x_shape(x.shape(), compress_time));
  int64_t f = x.dim(2);
  uint32_t time_mode = !compress_time || f <= 1 ? 0 : (f % 2 == 1 ? 1 : 2);
  struct {
    uint32_t frames, h, w, frames_out, time_mode, z_begin, row_begin, x_base, y_base;
  } pc{u32(op, f), u32(op, x.dim(3)), u32(op, x.dim(4)), u32(op, y.dim(2)), time_mode, 0, 0, 0, 0};
  if (y.numel() == 0) return;
  const ConvLimits l = conv_limits(rec.context().caps());
  expect(uint64_t(div_up(pc.w, 64)) <= l.groups_x, op, "input too large: " + x.describe());
  const int64_t h = x.dim(3), w = x.dim(4), fo = y.dim(2);
  const uint64_t align = std::lcm<uint64_t>(l.align, 8);  // y is bound as vec2s
  auto src_plane = [&](int64_t z) {
    const int64_t o = z % fo, bcz = z / fo;
    return bcz * f + (time_mode == 0 ? o : time_mode == 1 ? (o == 0 ? 0 : 1 + (o - 1) / 2) : o / 2);
  };
  // Planes [z0, z0 + nz) of y x input rows [r0, r0 + nr): elements of x, then of y.
  auto spans = [&](int64_t z0, int64_t nz, int64_t r0, int64_t nr) {
    return std::array<uint64_t, 4>{uint64_t((src_plane(z0) * h + r0) * w), uint64_t((src_plane(z0 + nz - 1) * h + r0 + nr) * w),
                                   uint64_t((z0 * h + r0) * 4 * w), uint64_t(((z0 + nz - 1) * h + r0 + nr) * 4 * w)};
  };
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/upsample2x");
  for_each_plane_chunk(rec.context(), op, l, y.dim(0) * y.dim(1) * fo, h, [&](int64_t z0, int64_t nz, int64_t r0, int64_t nr) {
    auto s = spans(z0, nz, r0, nr);
    return (s[1] - s[0]) * 4 + align <= l.storage && (s[3] - s[2]) * 4 + align <= l.storage;
  }, [&](int64_t z0, int64_t nz, int64_t r0, int64_t nr) {
    auto s = spans(z0, nz, r0, nr);
    pc.z_begin = uint32_t(z0), pc.row_begin = uint32_t(r0);
    const bool whole = uint64_t(x.bytes()) <= l.storage && uint64_t(y.bytes()) <= l.storage;
    vk::BufferView xv = whole ? x.buffer() : aligned_view(x.buffer(), s[0] * 4, s[1] * 4, l.align, 4, pc.x_base);
    vk::BufferView yv = whole ? y.buffer() : aligned_view(y.buffer(), s[2] * 4, s[3] * 4, align, 8, pc.y_base);
    rec.dispatch(pipe, {xv, yv}, &pc, sizeof pc, div_up(pc.w, 64), uint32_t(nr), uint32_t(nz), op);
  });
}

}  // namespace dvs::ops
