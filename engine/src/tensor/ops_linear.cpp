#include "tensor/ops_linear.hpp"

#include <algorithm>
#include <string>

#include "dvs/error.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/coopmat_layout.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_census.hpp"
#include "tensor/kernel_tuning.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops {
namespace {

constexpr const char* kOp = "linear";

struct Push {
  uint32_t M, N, K, ldx, ldy, ldw;
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

// `k` on the tiled family. Its register blocks stay at most 4x4 (tiles up to 64x64): with the coopmat entry's
// 128x128x32 (8x8 blocks) the H100 (driver 580) did not finish the first 37x45x24 call within 45 s, where
// 64x64x16 passed every check; a larger tile (the coopmat one, or linear=tiled on the gpu-coopmat entry) gets
// the tiled defaults.
LinearKernel as_tiled(LinearKernel k) {
  k.family = KernelFamily::tiled;
  if (k.tile_m > 64 || k.tile_n > 64) {
    const LinearKernel defaults;
    k.tile_m = defaults.tile_m;
    k.tile_n = defaults.tile_n;
    k.tile_k = defaults.tile_k;
  }
  return k;
}

}  // namespace

LinearKernel choose_linear_kernel(const vk::Context& ctx, const LinearShape& shape_in, DType w_dtype) {
  const LinearShape s = normalized(shape_in);
  const DeviceTuning& tune = device_tuning(ctx.caps());
  LinearKernel k;
  k.lanes = tune.gemm_lanes;
  // Few rows: every lane fetches the rows itself (GEMV-like); otherwise broadcast 8-row groups.
  // (Rows 2 also exists; M = 2..4 share the 4-row variant to keep the pipelines that LLVM compiles few.)
  if (s.m <= 1) k.rows = 1;
  else if (s.m <= 4) k.rows = 4;
  else k.rows = 8;
  k.cols = k.rows == 8 ? 3 : (k.rows == 1 ? 2 : 4);
  // f32 weights cost two texel fetches per 8 K values: a 16x2 tile (16 FMAs per fetch instead of 12)
  // measured ~10% faster on lavapipe; for 16-bit weights (one fetch per 8 values) 8x3 is as good and wastes
  // fewer rows on small M.
  if (tune.linear_f32_weights_16x2 && w_dtype == DType::f32 && s.m >= 64) {
    k.rows = 16;
    k.cols = 2;
  }
  k.sg_m = k.rows >= 8 ? 2 : 1;
  // The 8-value K steps need K and every X/W offset and stride on 8-element (W) / 4-element (X) boundaries;
  // strides are checked here and again at dispatch, offsets at dispatch where the bound views are known.
  k.vectorized = s.k % 8 == 0 && s.x_row_stride % 4 == 0 && s.x_batch_stride % 4 == 0 && s.w_batch_stride % 8 == 0;
  k.family = tune.linear;
  k.tile_m = tune.linear_tile_m;
  k.tile_n = tune.linear_tile_n;
  k.tile_k = tune.linear_tile_k;
  if (k.family == KernelFamily::coopmat) {
    const CoopmatGemm g = linear_coopmat_layout(tune, s.m, s.n);
    k.coopmat = g.tile;
    k.tile_m = int(g.tile_m());
    k.tile_n = int(g.tile_n());
    k.tile_k = g.tile.k;
    k.vectorized = k.vectorized && tune.linear_coopmat_vector_loads;
  }
  return k.family == KernelFamily::tiled ? as_tiled(k) : k;
}

DType gemm_weight_dtype(const vk::DeviceCaps& caps) {
  const DeviceTuning& tune = device_tuning(caps);
  return tune.linear == KernelFamily::coopmat && tune.linear_weights_fp16 ? DType::f16 : DType::bf16;
}

DType gemm_activation_dtype(const vk::DeviceCaps& caps) {
  const DeviceTuning& tune = device_tuning(caps);
  return tune.linear == KernelFamily::coopmat && tune.linear_activations_fp16 ? DType::f16 : DType::f32;
}

namespace {

// The coopmat family's layout of a kernel configuration: its own, or the tuning's where it has none (pinned).
CoopmatGemm kernel_coopmat_layout(const DeviceTuning& tune, const LinearKernel& kern) {
  CoopmatGemm g = linear_coopmat_layout(tune);
  if (kern.coopmat.defined()) g.tile = kern.coopmat;
  return g;
}

// The storage-buffer families' pipeline (tiled / coopmat) for a kernel configuration, after checking the tile
// against what the shader supports and the device's shared memory.
const vk::Pipeline& storage_pipeline(vk::Context& ctx, const LinearKernel& kern, uint32_t wcode, uint32_t xcode,
                                     bool y16, bool vec) {
  const vk::DeviceCaps& caps = ctx.caps();
  const uint32_t bm = uint32_t(kern.tile_m), bn = uint32_t(kern.tile_n), bk = uint32_t(kern.tile_k);
  const std::string tile = std::to_string(bm) + "x" + std::to_string(bn) + "x" + std::to_string(bk);
  if (kern.family == KernelFamily::tiled) {
    // 16 x 16 invocations, each a (bm/16) x (bn/16) register block.
    if (bm % 16 || bn % 16 || bm < 16 || bn < 16 || bm > 64 || bn > 64 || bk < 1 || bk > 64)
      fail("tiled kernel: tile " + tile + " unsupported (m, n multiples of 16 up to 64; k 1..64)");
    const uint64_t shared = uint64_t(bk) * (bm + 1 + bn + 1) * 4;
    if (shared > caps.max_compute_shared_memory)
      fail("tiled kernel: tile " + tile + " needs " + std::to_string(shared) + " bytes of shared memory");
    // Constant ids 7..12 are the coopmat kernel's (unused here); 13 is X's storage (linear_storage_io.glsl).
    const uint32_t spec[] = {bm, bn, wcode, bk, bm / 16, bn / 16, 256, 0, 0, 0, 0, 0, 0, xcode};
    return ctx.pipelines().get("linalg/linear_tiled", spec);
  }
  // coopmat: the configuration's layout (choose_linear_kernel's), whose tile its tile_m/n/k must be.
  const DeviceTuning& tune = device_tuning(caps);
  const CoopmatGemm g = kernel_coopmat_layout(tune, kern);
  if (int64_t(bm) != g.tile_m() || int64_t(bn) != g.tile_n() || int(bk) != g.tile.k)
    fail("coopmat kernel: tile " + tile + " is not its layout " + g.describe());
  const std::vector<uint32_t> spec = linear_coopmat_spec(g, wcode, vec, uint32_t(tune.linear_coopmat_group_m),
                                                         uint32_t(tune.linear_coopmat_ablation), xcode, y16);
  return coopmat_pipeline(ctx, "linalg/linear_coopmat", spec, uint32_t(g.lanes),
                          tune.coopmat.defined() ? linear_coopmat_unfit(caps, g)
                                                 : "no cooperative-matrix shape on " + caps.name);
}

// The coopmat2 GEMM's pipeline (linalg/linear_coopmat2.comp) for a call of the coopmat family, where the tuning asks
// for it, X and W are fp16 and the tuning's tile fits the device (linear_coopmat2_unfit); nullptr otherwise (the KHR
// kernel runs). Constant ids as the shader numbers them (2 and 13 are linear_storage_io.glsl's).
const vk::Pipeline* coopmat2_pipeline(vk::Context& ctx, const LinearKernel& kern, uint32_t wcode, uint32_t xcode,
                                      bool y16) {
  const DeviceTuning& tune = device_tuning(ctx.caps());
  if (kern.family != KernelFamily::coopmat || !tune.linear_coopmat2 || wcode != 1 || xcode != 1) return nullptr;
  const DeviceTuning::Coopmat2Tile& t = tune.linear_coopmat2_tile;
  if (!tune.linear_coopmat2_unfit.empty()) return nullptr;  // worked out once, with the tuning
  const uint32_t spec[] = {uint32_t(t.m), uint32_t(t.n), wcode, uint32_t(t.k), uint32_t(t.invocations), 0, 0, 0, 0, 0,
                           0, uint32_t(tune.linear_coopmat_group_m), 0, xcode, y16 ? 1u : 0u};
  return &ctx.pipelines().get("linalg/linear_coopmat2", spec);
}

// One dispatch's share of a call: batch items [b0, b0+bc), rows [m0, m0+mc), columns [n0, n0+nc), the
// products over k in [k0, k0+kc).
struct Chunk {
  int64_t b0 = 0, bc = 0, m0 = 0, mc = 0, n0 = 0, nc = 0, k0 = 0, kc = 0;
};

// Elements [first, first + count) of t as a tensor (bound later from an aligned-down offset).
Tensor elems(const Tensor& t, int64_t first, int64_t count) {
  const VkDeviceSize es = dtype_size(t.dtype());
  return Tensor::on(t.buffer().sub(VkDeviceSize(first) * es, VkDeviceSize(count) * es), {count}, t.dtype());
}

// What a call binds, and the limits it must stay within; a chunk fits when every view it binds (counted with
// the worst alignment slack) and its grid do.
struct Plan {
  const LinearShape& s;
  const LinearEpilogue& ep;
  uint64_t align, x_cap, w_cap, storage_cap;  // bytes
  size_t x_es, w_es;
  int64_t tile_m, tile_n;
  uint32_t max_groups[3];
  bool vec;  // 8-value K steps: K chunks start on multiples of 8
  bool y16;  // an f16 y, written in pairs: column chunks even, no K split

  bool fits(int64_t bc, int64_t mc, int64_t nc) const { return fits(bc, mc, nc, s.k); }
  bool fits(int64_t bc, int64_t mc, int64_t nc, int64_t kc) const {
    const uint64_t slack = align + 4;
    auto within = [&](int64_t count, uint64_t es, uint64_t cap) { return uint64_t(count) * es + slack <= cap; };
    const int64_t vec_elems = extent(bc, s.vec_batch_stride, 1, 0, nc);
    return within(extent(bc, s.x_batch_stride, mc, s.x_row_stride, kc), x_es, x_cap) &&
           within(extent(bc, s.w_batch_stride, nc, s.k, kc), w_es, w_cap) &&
           within(extent(bc, s.y_batch_stride, mc, s.y_row_stride, nc), 4, storage_cap) &&  // y and residual
           (!ep.bias.defined() || within(nc, dtype_size(ep.bias.dtype()), storage_cap)) &&
           (!(ep.scale.defined() || ep.gate.defined()) || within(vec_elems, 4, storage_cap)) &&
           div_up(nc, tile_n) <= max_groups[0] && div_up(mc, tile_m) <= max_groups[1] &&
           uint64_t(bc) <= max_groups[2];
  }

  // Largest v in [1, hi] with ok(v) (ok monotone: true up to some v), 0 when not even 1.
  template <class F>
  static int64_t largest(int64_t hi, F&& ok) {
    int64_t lo = 0;
    while (lo < hi) {
      int64_t mid = lo + (hi - lo + 1) / 2;
      if (ok(mid)) lo = mid; else hi = mid - 1;
    }
    return lo;
  }

  // Chunk sizes: everything at once when it fits (the common case: one dispatch); else one batch item at a
  // time, columns only when a weight slice / Y row / the x grid needs it (whole tiles), then rows (whole tiles).
  // K is split only when one row of X / W does not fit (never at model sizes: K <= 12288 floats, 48 KiB),
  // and only for epilogues that stay exact as y = (r +) Σ partial sums: no activation, modulation or gate.
  Chunk sizes() const {
    Chunk c{0, s.batch, 0, s.m, 0, s.n, 0, s.k};
    if (fits(s.batch, s.m, s.n)) return c;
    c.bc = largest(s.batch, [&](int64_t b) { return fits(b, s.m, s.n); });
    if (c.bc > 0) return c;
    c.bc = 1;
    if (!fits(1, 1, 1)) {
      if (ep.activation != Activation::none || ep.scale.defined() || ep.gate.defined() || y16)
        fail("one row of x / w (K = " + std::to_string(s.k) + ") does not fit one binding / texel view of the limits " +
             "in force, and a K split cannot apply an activation, modulation or gate, nor write an f16 y (K at most " +
             "12288 in the models)");
      c.kc = largest(s.k, [&](int64_t k) { return fits(1, 1, 1, k); });
      if (vec) c.kc = c.kc / 8 * 8;
      if (c.kc == 0) fail("not even one 8-value K step fits one binding / texel view");
    }
    if (!fits(1, 1, s.n, c.kc)) {
      c.nc = largest(s.n, [&](int64_t n) { return fits(1, 1, n, c.kc); });
      if (c.nc > tile_n) c.nc = c.nc / tile_n * tile_n;  // (tiles are even)
      else if (y16 && c.nc > 1) c.nc = c.nc / 2 * 2;     // every chunk's first column even
    }
    c.mc = largest(s.m, [&](int64_t m) { return fits(1, m, c.nc, c.kc); });
    if (c.mc < s.m && c.mc > tile_m) c.mc = c.mc / tile_m * tile_m;
    return c;
  }
};

}  // namespace

namespace {

// linear_batched_with, noting `fallback` (why the kernel is not the tuning's family) in the kernel census.
void record_linear(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor& y, const LinearShape& shape_in,
                   const LinearEpilogue& ep, LinearKernel kernel, const KernelFallback& fallback) {
  const LinearShape s = normalized(shape_in);
  if (s.batch < 0 || s.m < 0 || s.n < 0 || s.k < 0) fail("negative size");
  if (s.batch == 0 || s.m == 0 || s.n == 0) return;
  // X in f16 (written so by its producer where the GEMM runs on tensor cores): the storage families read it.
  if (x.dtype() != DType::f32 && !(x.dtype() == DType::f16 && kernel.family != KernelFamily::texel))
    fail("x must be f32 (or f16 on the tiled and coopmat families), got " + x.describe());
  const bool x16 = x.dtype() == DType::f16;
  const uint32_t xcode = x16 ? 1u : 0u, x_vec = x16 ? 8u : 4u;  // elements per 16-byte X vector
  // Y in f16 (the next GEMM's X) on the tensor-core family: written in pairs, so N and Y's strides even, no
  // residual and no K split (partial sums need f32).
  const bool y16 = y.dtype() == DType::f16;
  if (y16 && (kernel.family != KernelFamily::coopmat || s.n % 2 || s.y_row_stride % 2 || s.y_batch_stride % 2 ||
              ep.residual.defined()))
    fail("an f16 y needs the coopmat family, N and y's strides even and no residual, got " + y.describe() + " (N " +
         std::to_string(s.n) + ")");
  if (!y16) expect_f32("y", y);
  const uint32_t wcode = dtype_code(w.dtype(), "w");
  if (s.x_row_stride < s.k || s.y_row_stride < s.n) fail("row stride smaller than the row");
  expect_fits("x", x, extent(s.batch, s.x_batch_stride, s.m, s.x_row_stride, s.k));
  expect_fits("w", w, extent(s.batch, s.w_batch_stride, s.n, s.k, s.k));
  expect_fits("y", y, extent(s.batch, s.y_batch_stride, s.m, s.y_row_stride, s.n));

  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  const VkDeviceSize align = std::max<VkDeviceSize>(ctx.allocator().alignment(), binding_alignment(caps));
  Push p{};
  p.K = u32(s.k, "K");
  p.ldx = u32(s.x_row_stride, "x row stride");
  p.ldw = p.K;
  p.ldy = u32(s.y_row_stride, "y row stride");
  p.x_bs = u32(s.x_batch_stride, "x batch stride");
  p.w_bs = u32(s.w_batch_stride, "w batch stride");
  p.y_bs = u32(s.y_batch_stride, "y batch stride");
  p.vec_bs = u32(s.vec_batch_stride, "vector batch stride");
  p.flags = uint32_t(ep.activation);

  // K = 0: the product is zero, the epilogue still applies; a one-element zero view keeps bindings valid.
  // The 8-value path also needs the X/W offsets on 4/8-element boundaries: every chunk's offset keeps the
  // whole tensor's residue (chunk starts move by multiples of 8 elements), so the choice holds per chunk.
  // The coopmat kernel's 16-byte loads: the same rule (W's 8 values a uvec4 at 16 bits; f32 W as vec4, on
  // 4-value boundaries that the 8-value rule implies), and its invocations a multiple of the K step's X vectors.
  const bool vec_family =
      kernel.family == KernelFamily::texel ||
      (kernel.family == KernelFamily::coopmat && kernel.tile_k % 8 == 0 &&
       kernel_coopmat_layout(device_tuning(caps), kernel).invocations() % uint32_t(kernel.tile_k / 4) == 0);
  const bool vec = vec_family && kernel.vectorized && s.k > 0 && s.k % 8 == 0 && s.x_row_stride % x_vec == 0 &&
                   s.x_batch_stride % x_vec == 0 && s.w_batch_stride % 8 == 0;
  const bool use_vec =
      vec && bind_aligned(x, align).elem_off % x_vec == 0 && bind_aligned(w, align).elem_off % 8 == 0;
  const VkFormat x_fmt = use_vec ? VK_FORMAT_R32G32B32A32_SFLOAT : VK_FORMAT_R32_SFLOAT;
  const VkFormat w_fmt = use_vec ? VK_FORMAT_R32G32B32A32_UINT
                                 : (w.dtype() == DType::f32 ? VK_FORMAT_R32_UINT : VK_FORMAT_R16_UINT);
  const uint32_t xt = use_vec ? 16 : 4, wt = use_vec ? 16 : uint32_t(dtype_size(w.dtype()));

  const int64_t vec_extent = extent(s.batch, s.vec_batch_stride, 1, 0, s.n);
  uint32_t bias_code = 0;
  if (ep.bias.defined()) {
    bias_code = dtype_code(ep.bias.dtype(), "bias");
    expect_fits("bias", ep.bias, s.n);
    p.flags |= 4u | (bias_code << 6);
  }
  if (ep.scale.defined() != ep.shift.defined()) fail("modulation needs both scale and shift");
  if (ep.scale.defined()) {
    expect_f32("scale", ep.scale);
    expect_f32("shift", ep.shift);
    expect_fits("scale", ep.scale, vec_extent);
    expect_fits("shift", ep.shift, vec_extent);
    p.flags |= 8u;
  }
  if (ep.gate.defined()) {
    expect_f32("gate", ep.gate);
    expect_fits("gate", ep.gate, vec_extent);
    p.flags |= 16u;
  }
  if (ep.residual.defined()) {
    expect_f32("residual", ep.residual);
    expect_fits("residual", ep.residual, extent(s.batch, s.y_batch_stride, s.m, s.y_row_stride, s.n));
    p.flags |= 32u;
  }

  const bool storage = kernel.family != KernelFamily::texel;
  int64_t tile_m = 0, tile_n = 0;
  const vk::Pipeline* pipe_ptr = nullptr;
  if (!storage) {
    const int rows = kernel.rows, cols = kernel.cols;
    const int sg_m = rows >= 8 ? kernel.sg_m : 1;
    if (!(rows == 1 || rows == 2 || rows == 4 || rows == 8 || rows == 16) || cols < 1 || cols > 8 ||
        !(sg_m == 1 || sg_m == 2 || sg_m == 4 || sg_m == 8))
      fail("bad kernel configuration");
    const uint32_t spec[] = {uint32_t(rows), uint32_t(cols), wcode, use_vec ? 1u : 0u, uint32_t(kernel.lanes),
                             uint32_t(sg_m)};
    pipe_ptr = &ctx.pipelines().get(kernel.lanes == 2 ? "linalg/linear_nosubgroup" : "linalg/linear", spec);
    tile_m = int64_t(sg_m) * rows;
    tile_n = int64_t(8 / sg_m) * 8 * cols;
  } else if (const vk::Pipeline* cm2 = coopmat2_pipeline(ctx, kernel, wcode, xcode, y16)) {
    pipe_ptr = cm2;
    tile_m = device_tuning(caps).linear_coopmat2_tile.m;
    tile_n = device_tuning(caps).linear_coopmat2_tile.n;
  } else {
    pipe_ptr = &storage_pipeline(ctx, kernel, wcode, xcode, y16, use_vec);
    tile_m = kernel.tile_m;
    tile_n = kernel.tile_n;
  }
  const vk::Pipeline& pipe = *pipe_ptr;
  note_kernel(ctx, kOp, kernel.family, pipe.name, fallback);

  const Plan plan{s,
                  ep,
                  align,
                  storage ? binding_capacity(caps, 0) : binding_capacity(caps, xt),
                  storage ? binding_capacity(caps, 0) : binding_capacity(caps, wt),
                  binding_capacity(caps, 0),
                  dtype_size(x.dtype()),
                  dtype_size(w.dtype()),
                  tile_m,
                  tile_n,
                  {caps.max_workgroup_count[0], caps.max_workgroup_count[1], caps.max_workgroup_count[2]},
                  use_vec,
                  y16};
  const Chunk size = plan.sizes();

  // Each chunk binds only its own ranges: X rows, W rows (columns of Y), the Y/residual block, the vector
  // columns; offsets in the shader are relative to those views. K chunks after the first add their partial
  // products to Y (residual = Y, no bias).
  auto record = [&](const Chunk& c) {
    const bool first_k = c.k0 == 0;
    const int64_t x0 = c.b0 * s.x_batch_stride + c.m0 * s.x_row_stride + c.k0;
    const int64_t w0 = c.b0 * s.w_batch_stride + c.n0 * s.k + c.k0;
    const int64_t y0 = c.b0 * s.y_batch_stride + c.m0 * s.y_row_stride + c.n0, v0 = c.b0 * s.vec_batch_stride + c.n0;
    const int64_t y_len = extent(c.bc, s.y_batch_stride, c.mc, s.y_row_stride, c.nc);
    const int64_t v_len = extent(c.bc, s.vec_batch_stride, 1, 0, c.nc);
    // K = 0 binds one element (the views must not be empty).
    const int64_t x_len = extent(c.bc, s.x_batch_stride, c.mc, s.x_row_stride, c.kc);
    const int64_t w_len = extent(c.bc, s.w_batch_stride, c.nc, s.k, c.kc);
    Bound bx = storage ? bind_storage(elems(x, x0, std::max<int64_t>(x_len, 1)), align)
                       : bind_texels(elems(x, x0, std::max<int64_t>(x_len, 1)), align, xt);
    Bound bw = storage ? bind_storage(elems(w, w0, std::max<int64_t>(w_len, 1)), align)
                       : bind_texels(elems(w, w0, std::max<int64_t>(w_len, 1)), align, wt);
    Bound by = bind_storage(elems(y, y0, y_len), align);
    if ((use_vec && (bx.elem_off % x_vec || bw.elem_off % 8)) || bx.view.size == 0 || bw.view.size == 0)
      fail("a chunk's x/w offsets lost their alignment");
    if (y16 && (by.elem_off % 2 || !first_k)) fail("an f16 y needs an even offset and no K split");
    Push q = p;
    q.M = u32(c.mc, "M");
    q.N = u32(c.nc, "N");
    q.K = u32(c.kc, "K");
    q.x_off = bx.elem_off;
    q.w_off = bw.elem_off;
    q.y_off = by.elem_off;
    // Epilogue operands; absent ones bind x's storage (never read).
    Bound dummy = bind_storage(elems(x, x0, 1), align);
    Bound bbias = dummy, bscale = dummy, bshift = dummy, bgate = dummy, bres = dummy;
    if (ep.bias.defined() && first_k) bbias = bind_storage(elems(ep.bias, c.n0, c.nc), align);
    if (ep.scale.defined()) {
      bscale = bind_storage(elems(ep.scale, v0, v_len), align);
      bshift = bind_storage(elems(ep.shift, v0, v_len), align);
    }
    if (ep.gate.defined()) bgate = bind_storage(elems(ep.gate, v0, v_len), align);
    if (ep.residual.defined() && first_k) bres = bind_storage(elems(ep.residual, y0, y_len), align);
    if (!first_k) {
      q.flags = (q.flags & ~(4u | (3u << 6))) | 32u;
      bres = by;
    }
    q.bias_off = bbias.elem_off;
    q.scale_off = bscale.elem_off;
    q.shift_off = bshift.elem_off;
    q.gate_off = bgate.elem_off;
    q.res_off = bres.elem_off;
    const vk::Binding bxw[2] = {storage ? vk::Binding(bx.view) : vk::Binding(bx.view, x_fmt),
                                storage ? vk::Binding(bw.view) : vk::Binding(bw.view, w_fmt)};
    rec.dispatch(pipe, {bxw[0], bxw[1], by.view, bbias.view, bscale.view, bshift.view, bgate.view, bres.view}, &q,
                 sizeof q, div_up(c.nc, tile_n), div_up(c.mc, tile_m), u32(c.bc, "batch"),
                 !storage ? "linear" : kernel.family == KernelFamily::coopmat ? pipe.name.substr(7) : "linear_tiled");
  };
  if (size.bc < s.batch || size.nc < s.n || size.mc < s.m || size.kc < s.k) rec.context().note_split("linear");
  for_each_chunk(s.batch, size.bc, [&](int64_t b0, int64_t bc) {
    for_each_chunk(s.n, size.nc, [&](int64_t n0, int64_t nc) {
      for_each_chunk(s.m, size.mc, [&](int64_t m0, int64_t mc) {
        // K = 0 still records one dispatch (the epilogue on a zero product).
        for_each_chunk(std::max<int64_t>(s.k, 1), std::max<int64_t>(size.kc, 1), [&](int64_t k0, int64_t kc) {
          record({b0, bc, m0, mc, n0, nc, k0, std::min(kc, s.k)});
        });
      });
    });
  });
}

}  // namespace

void linear_batched_with(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor& y, const LinearShape& shape,
                         const LinearEpilogue& ep, LinearKernel kernel) {
  // A kernel chosen by choose_linear_kernel where the tuning's tensor cores do not fit is that fallback.
  const std::string& unfit = device_tuning(rec.context().caps()).linear_unfit;
  record_linear(rec, x, w, y, shape, ep, kernel,
                {kernel.family == KernelFamily::coopmat ? std::string() : unfit, true});
}

void linear_batched(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor& y, const LinearShape& shape,
                    const LinearEpilogue& ep) {
  LinearKernel k = choose_linear_kernel(rec.context(), shape, w.dtype());
  KernelFallback why{device_tuning(rec.context().caps()).linear_unfit, true};
  // fp16 operands could overflow for this caller: the fp32 tiled kernel.
  if (k.family == KernelFamily::coopmat && !ep.fp16_operands_ok) {
    k = as_tiled(k);
    why = {"the caller needs fp32 operands (LinearEpilogue::fp16_operands_ok)", false};
  }
  record_linear(rec, x, w, y, shape, ep, k, why);
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
