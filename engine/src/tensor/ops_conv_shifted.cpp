#include "tensor/ops_conv_shifted.hpp"

#include <algorithm>
#include <vector>

#include "tensor/binding_split.hpp"
#include "tensor/coopmat_layout.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_census.hpp"
#include "tensor/ops_conv_pack.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops::conv {
namespace {

struct ShiftedPush {
  uint32_t m, n, k, ldx, ldw, x_off, w_off, y_off, bias_off, x_bs, w_bs, kw, khw, wp, plane, rows, wo;
  uint32_t ys_f, ys_h, ys_w, ys_c, bias_type;
};
static_assert(sizeof(ShiftedPush) <= 128);

// One call's plan: the layout, and output channels, frames (or one frame's rows) per chunk.
struct Plan {
  CoopmatGemm g;
  int64_t cpc = 0, taps = 0, kt = 1, kh = 1, wp = 0, wo = 0, channels = 0, frames = 0, rows = 0;
  std::string refusal;  // "" when the call takes the kernel
  int64_t rows_p(int64_t nr) const { return nr + kh - 1; }  // the grid rows of nr output rows
  // Bytes of the fp16 grid of nfo output frames x nr rows (+ the repack's zero pixel).
  uint64_t packed_bytes(int64_t nfo, int64_t nr) const {
    return uint64_t(nfo + kt - 1) * uint64_t(rows_p(nr) * wp) * uint64_t(cpc) * 2 + uint64_t(cpc) * 2;
  }
  // The GEMM's rows: grid rows up to the chunk's last output pixel.
  int64_t gemm_rows(int64_t nfo, int64_t nr) const { return (nfo - 1) * rows_p(nr) * wp + (nr - 1) * wp + wo; }
};

// Elements of y that ng channels x nfo frames x nr rows span, first to last.
uint64_t y_span(const ConvJob& j, int64_t ng, int64_t nfo, int64_t nr) {
  return uint64_t((ng - 1) * j.ys_c + (nfo - 1) * j.ys_f + (nr - 1) * j.ys_h + (j.wo - 1) * j.ys_w + 1);
}

Plan plan(const vk::DeviceCaps& caps, const DeviceTuning& tune, const ConvJob& j, const ConvWeights& w,
          const ShiftedCall& call) {
  Plan p;
  auto refuse = [&](std::string why) {
    p.refusal = std::move(why);
    return p;
  };
  if (!tune.conv_shifted_gemm) return refuse("off (conv_shifted_gemm)");
  if (!call.coopmat) return refuse("the conv family is not the tensor-core kernel");
  if (!call.x_f16) return refuse("the input is repacked f32 (conv_activations_fp16)");
  if (j.stride != 1) return refuse("stride " + std::to_string(j.stride));
  const int64_t up = j.upsample ? 2 : 1;  // the grid is that of the x2 upsampling the call reads
  if (j.kh % 2 == 0 || j.kw % 2 == 0 || j.pad_top != (j.kh - 1) / 2 || j.pad_left != (j.kw - 1) / 2 ||
      j.ho != up * j.h || j.wo != up * j.w)
    return refuse("not a same-size convolution (odd kernel, padding (k - 1) / 2 on each side)");
  if (!w.packed()) return refuse("the weights are not packed at load");
  const DType wd = w.dtype();
  if (wd != DType::f16 && wd != DType::bf16 && wd != DType::f32) return refuse("weights " + w.describe());
  if (w.tensor().buffer().offset % 16 != 0) return refuse("the packed weights do not start 16-byte aligned");
  if (!tune.coopmat.defined()) return refuse("no cooperative-matrix shape on this device");
  p.g = linear_coopmat_layout(tune, j.frames_out * j.ho * j.wo, j.cout);
  p.cpc = (j.cin + 7) / 8 * 8;
  p.taps = j.kt * j.kh * j.kw;
  p.kt = j.kt, p.kh = j.kh;
  p.wp = j.wo + j.kw - 1, p.wo = j.wo;
  if (p.cpc % p.g.tile.k != 0)
    return refuse(std::to_string(p.cpc) + " packed input channels, not a multiple of the GEMM tile's K (" +
                  std::to_string(p.g.tile.k) + ")");
  // The 16-byte load path (the only one the step's shift is written for at full speed; the scalar one is the same
  // arithmetic): K per step a multiple of 8 and the workgroup whole rows of vectors.
  if (p.g.tile.k % 8 != 0 || p.g.invocations() % uint32_t(p.g.tile.k / 4) != 0)
    return refuse("layout " + p.g.describe() + " has no 16-byte loads");
  if (std::string unfit = linear_coopmat_unfit(caps, p.g); !unfit.empty()) return refuse(unfit);
  const ConvLimits l = conv_limits(caps);
  // Output channels per chunk: as many as one binding of y (and of the weights, and the grid) holds at one output
  // pixel, whole tiles where that is not all of them.
  const uint64_t y_cap = l.storage > l.align ? l.storage - l.align : 0;
  const uint64_t w_row = uint64_t(p.taps * p.cpc * int64_t(dtype_size(wd)));  // bytes of one channel's weights
  const uint64_t w_slack = std::max<uint64_t>(l.align, 16);  // a group's weights are bound from an aligned base
  auto group_fits = [&](int64_t ng) {
    return y_span(j, ng, 1, 1) * 4 <= y_cap && uint64_t(ng) * w_row + w_slack <= l.storage;
  };
  p.channels = j.cout;
  while (p.channels > 1 && !group_fits(p.channels))
    p.channels = p.channels > p.g.tile_n() ? (p.channels - 1) / p.g.tile_n() * p.g.tile_n() : p.channels - 1;
  if (!group_fits(p.channels)) return refuse("one output channel's row or weights exceed one binding");
  if (uint64_t((p.channels + p.g.tile_n() - 1) / p.g.tile_n()) > l.groups_x) return refuse("too many output channels");
  // Frames per chunk: the most whose repacked grid, grid rows and y fit; else one frame's rows.
  auto fits = [&](int64_t nfo, int64_t nr) {
    // The grid's elements must stay 32-bit indices in the shader.
    return p.packed_bytes(nfo, nr) <= call.input_bytes && p.packed_bytes(nfo, nr) / 2 < (1ull << 32) &&
           y_span(j, p.channels, nfo, nr) * 4 <= y_cap &&
           uint64_t((p.gemm_rows(nfo, nr) + p.g.tile_m() - 1) / p.g.tile_m()) <= l.groups_y;
  };
  for (int64_t n = j.frames_out; n >= 1 && p.frames == 0; --n)
    if (fits(n, j.ho)) p.frames = n, p.rows = j.ho;
  if (p.frames == 0) {
    for (int64_t r = j.ho - 1; r >= 1 && p.rows == 0; --r)
      if (fits(1, r)) p.frames = 1, p.rows = r;
  }
  if (p.frames == 0) return refuse("one output row's padded input does not fit one chunk");
  return p;
}

}  // namespace

std::string shifted_refusal(const vk::DeviceCaps& caps, const DeviceTuning& tune, const ConvJob& j,
                            const ConvWeights& w, const ShiftedCall& call) {
  return plan(caps, tune, j, w, call).refusal;
}

bool record_shifted(vk::Recorder& rec, const char* op, const ConvJob& j, const Tensor& x, const ConvWeights& w,
                    const Tensor* bias, const Tensor& y, const ShiftedCall& call) {
  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  const DeviceTuning& tune = device_tuning(caps);
  const Plan p = plan(caps, tune, j, w, call);
  if (!p.refusal.empty()) return false;
  const int64_t up = j.upsample ? 2 : 1;
  const ConvLimits l = conv_limits(caps);
  const std::vector<uint32_t> spec = linear_coopmat_spec(p.g, weight_code(op, w.dtype()), true,
                                                         uint32_t(tune.linear_coopmat_group_m), 0, 1, false);
  const vk::Pipeline& pipe = coopmat_pipeline(ctx, "nn/conv_shifted_coopmat", spec, uint32_t(p.g.lanes), "");
  note_kernel(ctx, "conv", KernelFamily::coopmat, pipe.name);
  if (p.channels < j.cout || p.frames < j.frames_out || p.rows < j.ho) ctx.note_split(std::string(op) + " as a GEMM");

  // Each group of output channels' weights, bound from a 16-byte aligned base (the 16-byte loads' unit) at element
  // w_off (bases below the view's start wrap, as in the shader).
  struct Group {
    int64_t n0, nn;
    vk::BufferView w;
    uint32_t w_off;
  };
  std::vector<Group> groups;
  const uint32_t wb = uint32_t(dtype_size(w.dtype()));
  const uint64_t w_row = uint64_t(p.taps * p.cpc) * wb;
  for_each_chunk(j.cout, p.channels, [&](int64_t n0, int64_t nn) {
    uint32_t base = 0;
    const vk::BufferView v = aligned_view(w.tensor().buffer(), uint64_t(n0) * w_row, uint64_t(n0 + nn) * w_row,
                                          std::max<uint64_t>(l.align, 16), wb, base);
    groups.push_back({n0, nn, v, uint32_t(uint64_t(n0) * w_row / wb) - base});
  });
  const vk::BufferView packed_all =
      call.given ? call.given->input.buffer()
                 : rec.scratch(0, p.packed_bytes(p.frames, p.rows), "convolution input chunk (repacked on its padded grid)");
  const vk::BufferView bias_view = bias_binding(x, bias);
  const uint32_t bias_type = bias ? weight_code(op, bias->dtype()) + 1 : 0u;
  for (int64_t b = 0; b < j.b; ++b)
    for_each_chunk(j.frames_out, p.frames, [&](int64_t fo0, int64_t nfo) {
      for_each_chunk(j.ho, p.rows, [&](int64_t oh0, int64_t nr) {
        // The chunk's grid, packed once for every channel group: output rows [oh0, oh0 + nr) read grid rows from
        // oh0 - pad_top, zero outside the image (rows of the x2 upsampling where the call reads it; the pack maps
        // them to x's).
        const int64_t r0 = std::max<int64_t>(oh0 - j.pad_top, 0);
        const int64_t r1 = std::min<int64_t>(oh0 + nr - 1 - j.pad_top + j.kh - 1, up * j.h - 1);  // last row read
        const int64_t rp = p.rows_p(nr), m = p.gemm_rows(nfo, nr);
        vk::BufferView packed = packed_all;
        packed.size = p.packed_bytes(nfo, nr);
        pack_input(rec, op, j, x, l, b, 0, j.cin, p.cpc, fo0, nfo + j.kt - 1, r0, r1 - r0 + 1, 0, up * j.w, true,
                   packed, call.pack_columns, PackGrid{r0 - (oh0 - j.pad_top), rp, j.pad_left, p.wp, up});
        for (const Group& gr : groups) {
          ShiftedPush pc{};
          pc.m = u32(op, m), pc.n = u32(op, gr.nn), pc.k = u32(op, p.taps * p.cpc);
          pc.ldx = u32(op, p.cpc), pc.ldw = u32(op, p.taps * p.cpc), pc.w_off = gr.w_off;
          pc.kw = u32(op, j.kw), pc.khw = u32(op, j.kh * j.kw), pc.wp = u32(op, p.wp), pc.plane = u32(op, rp * p.wp);
          pc.rows = u32(op, nr), pc.wo = u32(op, j.wo);
          pc.ys_f = u32(op, j.ys_f), pc.ys_h = u32(op, j.ys_h), pc.ys_w = u32(op, j.ys_w), pc.ys_c = u32(op, j.ys_c);
          pc.bias_type = bias_type, pc.bias_off = u32(op, gr.n0);
          const uint64_t y0 = uint64_t(b * j.ys_b + fo0 * j.ys_f + oh0 * j.ys_h + gr.n0 * j.ys_c);
          uint32_t ybase = 0;
          const vk::BufferView yv = aligned_view(y.buffer(), y0 * 4, (y0 + y_span(j, gr.nn, nfo, nr)) * 4, l.align, 4, ybase);
          pc.y_off = uint32_t(y0) - ybase;
          rec.dispatch(pipe, {packed, gr.w, bias_view, yv}, &pc, sizeof pc,
                       u32(op, (gr.nn + p.g.tile_n() - 1) / p.g.tile_n()), u32(op, (m + p.g.tile_m() - 1) / p.g.tile_m()),
                       1, op);
        }
      });
    });
  return true;
}

}  // namespace dvs::ops::conv
