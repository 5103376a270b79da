#include "tensor/ops_linear.hpp"

#include <algorithm>
#include <string>

#include "dvs/error.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops {
namespace {

constexpr const char* kOp = "linear";

struct Push {
  uint32_t M, N, K, ldx, ldy;
  uint32_t x_off, w_off, y_off;
  uint32_t x_bs, w_bs, y_bs;
  uint32_t bias_off, scale_off, shift_off, gate_off, res_off;
  uint32_t vec_bs;
  uint32_t flags;
};
static_assert(sizeof(Push) <= 128);

[[noreturn]] void fail(const std::string& what) { throw Error(std::string("internal: ") + kOp + ": " + what); }

uint32_t u32(int64_t v, const char* what) {
  if (v < 0 || v > int64_t(UINT32_MAX)) fail(std::string(what) + " out of range (" + std::to_string(v) + ")");
  return uint32_t(v);
}

// A tensor bound from an aligned-down offset (texel and storage views need aligned offsets; tensor slices
// may start anywhere): the shader adds `elem_off` elements.
struct Bound {
  vk::BufferView view;
  uint32_t elem_off = 0;
};

Bound bind_aligned(const Tensor& t, VkDeviceSize align) {
  const vk::BufferView& v = t.buffer();
  size_t es = dtype_size(t.dtype());
  VkDeviceSize delta = v.offset % align;
  if (delta % es) fail("tensor " + t.describe() + " is not aligned to its element size");
  Bound b;
  b.view = v;
  b.view.offset -= delta;
  if (b.view.mapped) b.view.mapped -= delta;
  b.view.size = v.size + delta;
  b.elem_off = uint32_t(delta / es);
  return b;
}

// Texel views cover whole texels: the range is rounded down (every texel the shader fetches lies inside).
Bound bind_texels(const Tensor& t, VkDeviceSize align, VkDeviceSize texel_bytes) {
  Bound b = bind_aligned(t, align);
  b.view.size = b.view.size / texel_bytes * texel_bytes;
  return b;
}

// Storage views of 16-bit data are read as whole 32-bit words: round up (allocations are padded to the
// allocator's alignment, so the last word stays inside the allocation).
Bound bind_storage(const Tensor& t, VkDeviceSize align) {
  Bound b = bind_aligned(t, align);
  b.view.size = (b.view.size + 3) / 4 * 4;
  return b;
}

// Largest element index (+1) that a [batch][rows][cols] walk touches.
int64_t extent(int64_t batch, int64_t batch_stride, int64_t rows, int64_t row_stride, int64_t cols) {
  if (batch == 0 || rows == 0 || cols == 0) return 0;
  return (batch - 1) * batch_stride + (rows - 1) * row_stride + cols;
}

void expect_fits(const char* arg, const Tensor& t, int64_t needed) {
  if (needed > t.numel())
    fail(std::string(arg) + " " + t.describe() + " is too small for the layout (needs " + std::to_string(needed) +
         " elements)");
}

void expect_f32(const char* arg, const Tensor& t) {
  if (t.dtype() != DType::f32) fail(std::string(arg) + " must be f32, got " + t.describe());
}

uint32_t dtype_code(DType d, const char* arg) {
  switch (d) {
    case DType::f32: return 0;
    case DType::f16: return 1;
    case DType::bf16: return 2;
    default: fail(std::string(arg) + " must be f32, f16 or bf16");
  }
}

LinearShape normalized(const LinearShape& s) {
  LinearShape r = s;
  if (r.x_row_stride == 0) r.x_row_stride = r.k;
  if (r.y_row_stride == 0) r.y_row_stride = r.n;
  return r;
}

}  // namespace

LinearKernel choose_linear_kernel(const vk::Context& ctx, const LinearShape& shape_in, DType w_dtype) {
  const LinearShape s = normalized(shape_in);
  const vk::DeviceCaps& caps = ctx.caps();
  LinearKernel k;
  if (caps.subgroup_shuffle && caps.subgroup_size == 8)
    k.lanes = 0;
  else if (caps.subgroup_shuffle && caps.subgroup_size >= 8 && caps.subgroup_size <= 64 && caps.subgroup_size % 8 == 0)
    k.lanes = 1;
  else
    k.lanes = 2;
  // Few rows: every lane fetches the rows itself (GEMV-like); otherwise broadcast 8-row groups.
  // (Rows 2 also exists; M = 2..4 share the 4-row variant to keep the pipelines that LLVM compiles few.)
  if (s.m <= 1) k.rows = 1;
  else if (s.m <= 4) k.rows = 4;
  else k.rows = 8;
  k.cols = k.rows == 8 ? 3 : (k.rows == 1 ? 2 : 4);
  // f32 weights cost two texel fetches per 8 K values: a 16x2 tile (16 FMAs per fetch instead of 12)
  // measured ~10% faster on lavapipe; for 16-bit weights (one fetch per 8 values) 8x3 is as good and wastes
  // fewer rows on small M.
  if (w_dtype == DType::f32 && s.m >= 64) {
    k.rows = 16;
    k.cols = 2;
  }
  k.sg_m = k.rows >= 8 ? 2 : 1;
  // The 8-value K steps need K and every X/W offset and stride on 8-element (W) / 4-element (X) boundaries;
  // strides are checked here and again at dispatch, offsets at dispatch where the bound views are known.
  k.vectorized = s.k % 8 == 0 && s.x_row_stride % 4 == 0 && s.x_batch_stride % 4 == 0 && s.w_batch_stride % 8 == 0;
  return k;
}

void linear_batched_with(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor& y, const LinearShape& shape_in,
                         const LinearEpilogue& ep, LinearKernel kernel) {
  const LinearShape s = normalized(shape_in);
  if (s.batch < 0 || s.m < 0 || s.n < 0 || s.k < 0) fail("negative size");
  if (s.batch == 0 || s.m == 0 || s.n == 0) return;
  expect_f32("x", x);
  expect_f32("y", y);
  const uint32_t wcode = dtype_code(w.dtype(), "w");
  if (s.x_row_stride < s.k || s.y_row_stride < s.n) fail("row stride smaller than the row");
  expect_fits("x", x, extent(s.batch, s.x_batch_stride, s.m, s.x_row_stride, s.k));
  expect_fits("w", w, extent(s.batch, s.w_batch_stride, s.n, s.k, s.k));
  expect_fits("y", y, extent(s.batch, s.y_batch_stride, s.m, s.y_row_stride, s.n));

  vk::Context& ctx = rec.context();
  const VkDeviceSize align = ctx.allocator().alignment();
  Push p{};
  p.M = u32(s.m, "M");
  p.N = u32(s.n, "N");
  p.K = u32(s.k, "K");
  p.ldx = u32(s.x_row_stride, "x row stride");
  p.ldy = u32(s.y_row_stride, "y row stride");
  p.x_bs = u32(s.x_batch_stride, "x batch stride");
  p.w_bs = u32(s.w_batch_stride, "w batch stride");
  p.y_bs = u32(s.y_batch_stride, "y batch stride");
  p.vec_bs = u32(s.vec_batch_stride, "vector batch stride");
  p.flags = uint32_t(ep.activation);

  // K = 0: the product is zero, the epilogue still applies; a one-element zero view keeps bindings valid.
  const bool vec = kernel.vectorized && s.k > 0 && s.k % 8 == 0 && s.x_row_stride % 4 == 0 &&
                   s.x_batch_stride % 4 == 0 && s.w_batch_stride % 8 == 0;
  Bound bx = bind_texels(x, align, vec ? 16 : 4);
  Bound bw = bind_texels(w, align, vec ? 16 : dtype_size(w.dtype()));
  Bound by = bind_storage(y, align);
  p.x_off = bx.elem_off;
  p.w_off = bw.elem_off;
  p.y_off = by.elem_off;
  bool use_vec = vec && p.x_off % 4 == 0 && p.w_off % 8 == 0;
  if (!use_vec && vec) {  // offsets forced the scalar path: rebind with scalar texels
    bx = bind_texels(x, align, 4);
    bw = bind_texels(w, align, dtype_size(w.dtype()));
  }
  const VkFormat x_fmt = use_vec ? VK_FORMAT_R32G32B32A32_SFLOAT : VK_FORMAT_R32_SFLOAT;
  const VkFormat w_fmt = use_vec ? VK_FORMAT_R32G32B32A32_UINT
                                 : (w.dtype() == DType::f32 ? VK_FORMAT_R32_UINT : VK_FORMAT_R16_UINT);
  const uint64_t max_texels = ctx.caps().max_texel_buffer_elements;
  const VkDeviceSize xt = use_vec ? 16 : 4, wt = use_vec ? 16 : dtype_size(w.dtype());
  if (max_texels && (bx.view.size / xt > max_texels || bw.view.size / wt > max_texels))
    fail("x or w exceeds the device's maxTexelBufferElements; split the call");

  // Epilogue operands; absent ones bind x's storage (never read).
  Bound dummy = bind_storage(x, align);
  Bound bbias = dummy, bscale = dummy, bshift = dummy, bgate = dummy, bres = dummy;
  const int64_t vec_extent = extent(s.batch, s.vec_batch_stride, 1, 0, s.n);
  if (ep.bias.defined()) {
    uint32_t code = dtype_code(ep.bias.dtype(), "bias");
    expect_fits("bias", ep.bias, s.n);
    bbias = bind_storage(ep.bias, align);
    p.bias_off = bbias.elem_off;
    p.flags |= 4u | (code << 6);
  }
  if (ep.scale.defined() != ep.shift.defined()) fail("modulation needs both scale and shift");
  if (ep.scale.defined()) {
    expect_f32("scale", ep.scale);
    expect_f32("shift", ep.shift);
    expect_fits("scale", ep.scale, vec_extent);
    expect_fits("shift", ep.shift, vec_extent);
    bscale = bind_storage(ep.scale, align);
    bshift = bind_storage(ep.shift, align);
    p.scale_off = bscale.elem_off;
    p.shift_off = bshift.elem_off;
    p.flags |= 8u;
  }
  if (ep.gate.defined()) {
    expect_f32("gate", ep.gate);
    expect_fits("gate", ep.gate, vec_extent);
    bgate = bind_storage(ep.gate, align);
    p.gate_off = bgate.elem_off;
    p.flags |= 16u;
  }
  if (ep.residual.defined()) {
    expect_f32("residual", ep.residual);
    expect_fits("residual", ep.residual, extent(s.batch, s.y_batch_stride, s.m, s.y_row_stride, s.n));
    bres = bind_storage(ep.residual, align);
    p.res_off = bres.elem_off;
    p.flags |= 32u;
  }

  const int rows = kernel.rows, cols = kernel.cols;
  const int sg_m = rows >= 8 ? kernel.sg_m : 1;
  if (!(rows == 1 || rows == 2 || rows == 4 || rows == 8 || rows == 16) || cols < 1 || cols > 8 ||
      !(sg_m == 1 || sg_m == 2 || sg_m == 4 || sg_m == 8))
    fail("bad kernel configuration");
  const uint32_t spec[] = {uint32_t(rows), uint32_t(cols), wcode, use_vec ? 1u : 0u, uint32_t(kernel.lanes),
                           uint32_t(sg_m)};
  const vk::Pipeline& pipe = ctx.pipelines().get(kernel.lanes == 2 ? "linalg/linear_nosubgroup" : "linalg/linear", spec);
  const int64_t tile_m = int64_t(sg_m) * rows, tile_n = int64_t(8 / sg_m) * 8 * cols;
  const uint32_t gx = div_up(s.n, tile_n), gy = div_up(s.m, tile_m), gz = u32(s.batch, "batch");
  if (gy > 65535 || gz > 65535) fail("too many rows or batch items for one dispatch; split the call");
  rec.dispatch(pipe,
               {vk::Binding(bx.view, x_fmt), vk::Binding(bw.view, w_fmt), by.view, bbias.view, bscale.view,
                bshift.view, bgate.view, bres.view},
               &p, sizeof p, gx, gy, gz, "linear");
}

void linear_batched(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor& y, const LinearShape& shape,
                    const LinearEpilogue& ep) {
  linear_batched_with(rec, x, w, y, shape, ep, choose_linear_kernel(rec.context(), shape, w.dtype()));
}

void linear(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor& y, const LinearEpilogue& ep) {
  if (w.rank() != 2) fail("w must be [N, K], got " + w.describe());
  const int64_t n = w.dim(0), k = w.dim(1);
  if (x.rank() < 1 || x.dim(-1) != k) fail("x " + x.describe() + " does not end in K = " + std::to_string(k));
  const int64_t m = x.numel() / std::max<int64_t>(k, 1);
  Shape ys = x.shape();
  ys.back() = n;
  if (y.shape() != ys) fail("y is " + y.describe() + ", expected [" + shape_str(ys) + "]");
  LinearShape s;
  s.m = k ? m : y.numel() / std::max<int64_t>(n, 1);
  s.n = n;
  s.k = k;
  if (ep.residual.defined() && ep.residual.shape() != ys)
    fail("residual is " + ep.residual.describe() + ", expected [" + shape_str(ys) + "]");
  if (ep.bias.defined() && ep.bias.numel() != n) fail("bias is " + ep.bias.describe() + ", expected " + std::to_string(n) + " values");
  for (const Tensor* v : {&ep.scale, &ep.shift, &ep.gate})
    if (v->defined() && v->numel() != n) fail("gate/scale/shift must have N values in linear(); use linear_batched for per-item vectors");
  linear_batched(rec, x, w, y, s, ep);
}

}  // namespace dvs::ops
