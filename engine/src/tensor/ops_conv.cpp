#include "tensor/ops_conv.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <string>

#include "dvs/error.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/coopmat_layout.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_census.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv_coopmat2.hpp"
#include "tensor/ops_conv_job.hpp"
#include "tensor/ops_conv_pack.hpp"
#include "tensor/ops_conv_shifted.hpp"
#include "tensor/ops_conv_weights.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

using conv::ConvJob;
using conv::ConvLimits;
using conv::conv_limits;
using conv::expect;
using conv::fail;
using conv::RowSpan;
using conv::u32;
using conv::weight_code;

constexpr uint32_t kMaxCachePrefix = 4;  // shaders/nn/conv3d_cache.comp MAXP

ConvRegisterBlock g_block_override;
uint64_t g_chunk_bytes_override = 0;

// Pixels of a row per invocation of the input repack: the override's, else the tuning's.
int64_t pack_columns(const vk::DeviceCaps& caps) {
  return g_block_override.pack_columns ? g_block_override.pack_columns : conv_pack_columns(caps);
}

// The GEMM family of this device (and its workgroup tile, pixels x channels, for the storage-buffer ones).
struct ConvFamily {
  KernelFamily kind = KernelFamily::texel;
  int64_t tile_m = 0, tile_n = 0;
  bool twin = false;  // coopmat tiling run by the fp32 twin shader (ConvRegisterBlock::coopmat_twin)
  CoopmatGemm layout;  // coopmat: the tuning's layout (tile_m x tile_n its tile)
};
ConvFamily conv_family(const vk::DeviceCaps& caps) {
  const DeviceTuning& t = device_tuning(caps);
  ConvFamily f;
  f.kind = g_block_override.coopmat_twin ? KernelFamily::coopmat : t.conv;
  f.twin = g_block_override.coopmat_twin;
  if (f.kind == KernelFamily::tiled) f.tile_m = t.conv_tile_m, f.tile_n = t.conv_tile_n;
  if (f.kind == KernelFamily::coopmat) {
    f.layout = conv_coopmat_layout(t);
    f.tile_m = f.layout.tile_m(), f.tile_n = f.layout.tile_n();
  }
  return f;
}

struct GemmPush {
  uint32_t m, n, cp, kt, kh, kw, stride, up, wo, rows, oh0;
  int32_t pad_top, pad_left;
  uint32_t in_h, in_w, src_r0, src_rows, src_w, zero_texel, y_base;
  uint32_t ys_f, ys_h, ys_w, ys_c, has_bias, n_base, accumulate, ow0, src_c0;
};
static_assert(sizeof(GemmPush) <= 128);


// The bias has a dtype of its own (weights packed at load in fp16 keep a bf16 bias exact): shaders' BTYPE.
void check_bias(const char* op, const Tensor* bias, int64_t cout) {
  if (!bias) return;
  weight_code(op, bias->dtype());
  expect(bias->numel() == cout, op, "bias " + bias->describe() + " must hold Cout = " + std::to_string(cout) + " values");
}

constexpr uint64_t kScratchInputCap = 128ull << 20;  // bytes; see ConvScratch

// f32 elements of a convolution's staging: the whole repacked input (capped) and the repacked weights.
ConvScratchSize scratch_size(int64_t frames_out, int64_t kt, int64_t h, int64_t w, int64_t cin, int64_t cout,
                             int64_t taps) {
  const int64_t cp = (cin + 7) / 8 * 8;
  uint64_t input = uint64_t(frames_out + kt - 1) * uint64_t(h * w) * uint64_t(cp) * 4 + uint64_t(cp) * 4;
  uint64_t weights = uint64_t(cout * taps * cp) * 4;  // f32, the largest weight dtype
  return {int64_t(std::min(input, kScratchInputCap) / 4), int64_t(std::min(weights, kScratchInputCap) / 4)};
}

// The convolution, split so that every dispatch stays within the limits in force:
//  - input channels in chunks of cc (a multiple of 8) when one output row's repacked input or one output
//    channel's weights would not fit one binding; later chunks add into y (fp32, bias with the first);
//  - output channels in groups of ng: y is bound per group (channels-first y spans ys_c per channel), the
//    group's weights are repacked per group (a binding, a texel view, the scratch), gy within the grid limit;
//  - per batch item, output frames and, when one frame is too large, output rows (then columns): the chunk's input repacked
//    channels-last stays within one binding / texel view / the scratch, its pixels within the grid limit.
// When everything fits (the default on real devices at small sizes) this is one weight pack (none for weights
// packed at load: ops_conv_weights.hpp), then one input pack and one GEMM per chunk of frames.
void record_conv(vk::Recorder& rec, const char* op, const ConvJob& j, const Tensor& x, const ConvWeights& w,
                 const Tensor* bias, const Tensor& y, const ConvScratch* given) {
  if (j.b == 0 || j.frames_out == 0 || j.ho == 0 || j.wo == 0 || j.cout == 0) return;
  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  const ConvLimits l = conv_limits(caps);
  const uint32_t wdt = weight_code(op, w.dtype()), bdt = bias ? weight_code(op, bias->dtype()) : wdt;
  const int64_t up = j.upsample ? 2 : 1, taps = j.kt * j.kh * j.kw, wb = wdt == 0 ? 4 : 2;

  GemmTile tile = conv_tile(caps, w.dtype(), j.frames_out * j.ho * j.wo, j.cout);
  if (g_block_override.rows) tile.rows = g_block_override.rows;
  if (g_block_override.cols) tile.cols = g_block_override.cols;
  if (g_block_override.k_unroll) tile.k_unroll = g_block_override.k_unroll;
  if (g_block_override.lanes >= 0) tile.lanes = std::max(g_block_override.lanes, gemm_lanes(caps));
  // The GEMM kernel family (kernel_tuning.hpp): texel (conv_gemm.comp), tiled (conv_tiled.comp) or coopmat
  // (conv_coopmat.comp; its fp32 twin when a test asks for it). All three read the same repacked operands
  // with the same push constants and serve every variant (2D/3D, strides, upsampling, channels-last y).
  const ConvFamily fam = conv_family(caps);
  // The repacked input: fp16 where the tensor-core kernel reads it (its operand type), else f32.
  const bool x16 = conv_repack_dtype(caps) == DType::f16;
  const uint64_t xb = x16 ? 2 : 4;
  int64_t tile_m = int64_t(tile.sg_m) * tile.rows, tile_n = int64_t(8 / tile.sg_m) * 8 * tile.cols;
  if (fam.kind != KernelFamily::texel) tile_m = fam.tile_m, tile_n = fam.tile_n;

  // Staging budgets: one binding (and one RGBA texel view for the texel family), one allocation, the
  // caller's buffer.
  const uint64_t alloc = caps.max_memory_allocation_size ? caps.max_memory_allocation_size : UINT64_MAX;
  const uint64_t view_cap = fam.kind == KernelFamily::texel ? l.rgba : binding_capacity(caps, 0);
  uint64_t in_cap = std::min({view_cap, alloc, kScratchInputCap});
  uint64_t w_cap = std::min({view_cap, alloc, kScratchInputCap});
  if (given) in_cap = std::min<uint64_t>(in_cap, uint64_t(given->input.bytes()));
  if (given) w_cap = std::min<uint64_t>(w_cap, uint64_t(given->weights.bytes()));
  if (g_chunk_bytes_override) in_cap = std::min<uint64_t>(in_cap, g_chunk_bytes_override);
  in_cap = std::min<uint64_t>(in_cap, l.groups_1d * 64 * 4 * xb);  // one pack dispatch's grid (4 channels each)
  // A same-size convolution through the GEMM kernel itself where the tuning asks for it and the call allows
  // (ops_conv_shifted.hpp); the implicit-GEMM kernels below otherwise.
  if (conv::record_shifted(rec, op, j, x, w, bias, y,
                           {fam.kind == KernelFamily::coopmat && !fam.twin, x16, pack_columns(caps), in_cap, given}))
    return;
  const uint64_t y_cap = l.storage > l.align ? l.storage - l.align : 0;

  // Source rows of r output rows, wherever they lie (interior rows read the most: the span plus the kernel,
  // halved and rounded out when upsampling).
  auto src_of = [&](int64_t r, int64_t total, int64_t k, int64_t n, RowSpan whole) {
    if (r == total) return whole.end - whole.first;
    int64_t span = (r - 1) * j.stride + k;
    return std::min(n, up == 1 ? span : (span - 1) / 2 + 2);
  };
  const RowSpan all_rows = source_rows(j, 0, j.ho), all_cols = source_cols(j, 0, j.wo);
  // Bytes of the repacked input of nfo output frames x r rows x c columns (+ the zero pixel).
  auto chunk_bytes = [&](int64_t nfo, int64_t r, int64_t cpc, int64_t c) {
    return uint64_t(nfo + j.kt - 1) * uint64_t(src_of(r, j.ho, j.kh, j.h, all_rows)) *
               uint64_t(src_of(c, j.wo, j.kw, j.w, all_cols)) * uint64_t(cpc) * xb + uint64_t(cpc) * xb;
  };
  // Elements of y one dispatch of ng channels, nfo frames, r rows and c columns writes, first to last.
  auto y_span = [&](int64_t ng, int64_t nfo, int64_t r, int64_t c) {
    return uint64_t((ng - 1) * j.ys_c + (nfo - 1) * j.ys_f + (r - 1) * j.ys_h + (c - 1) * j.ys_w + 1);
  };
  auto round8 = [](int64_t c) { return (c + 7) / 8 * 8; };

  // Input channels per chunk: all, unless one output pixel or one output channel's weights do not fit.
  int64_t cc = j.cin;
  auto cc_fits = [&](int64_t c) {
    int64_t cpc = round8(c);
    return chunk_bytes(1, 1, cpc, 1) <= in_cap && uint64_t(taps * cpc * wb) <= w_cap &&
           uint64_t(c * taps * wb) + l.align + 4 <= l.storage;
  };
  if (!cc_fits(cc)) {
    cc = (cc - 1) / 8 * 8;
    while (cc > 8 && !cc_fits(cc)) cc -= 8;
    expect(cc >= 1 && cc_fits(cc), op, "not even 8 input channels of one output pixel fit the limits in force");
  }
  const int64_t cpc = round8(cc);

  // Output channels per group.
  int64_t ng = j.cout;
  ng = std::min<int64_t>(ng, int64_t(w_cap / uint64_t(taps * cpc * wb)));
  ng = std::min<int64_t>(ng, int64_t(l.groups_y) * tile_n);
  if (y_span(ng, 1, 1, 1) * 4 > y_cap && j.ys_c > 0)
    ng = std::min<int64_t>(ng, int64_t((y_cap / 4 - y_span(1, 1, 1, 1)) / uint64_t(j.ys_c)) + 1);
  expect(ng >= 1 && y_span(1, 1, 1, 1) * 4 <= y_cap, op, "one output pixel exceeds one binding");
  if (ng < j.cout && ng > tile_n) ng = ng / tile_n * tile_n;  // whole tiles per group

  // Output frames, then rows, per chunk.
  const uint64_t max_m = l.groups_x * uint64_t(tile_m);
  auto chunk_fits = [&](int64_t nfo, int64_t r, int64_t c) {
    return chunk_bytes(nfo, r, cpc, c) <= in_cap && uint64_t(nfo * r * c) <= max_m && y_span(ng, nfo, r, c) * 4 <= y_cap;
  };
  int64_t chunk_frames = 0, chunk_rows = j.ho, chunk_cols = j.wo;
  for (int64_t n = j.frames_out; n >= 1 && chunk_frames == 0; --n)
    if (chunk_fits(n, j.ho, j.wo)) chunk_frames = n;
  if (chunk_frames == 0) {  // one frame at a time, in rows
    chunk_frames = 1;
    chunk_rows = 0;
    for (int64_t r = j.ho - 1; r >= 1 && chunk_rows == 0; --r)
      if (chunk_fits(1, r, j.wo)) chunk_rows = r;
  }
  if (chunk_rows == 0) {  // one row at a time, in columns
    chunk_rows = 1;
    chunk_cols = 0;
    for (int64_t c = j.wo - 1; c >= 1 && chunk_cols == 0; --c)
      if (chunk_fits(1, 1, c)) chunk_cols = c;
    expect(chunk_cols >= 1, op, "one output pixel of " + x.describe() + " does not fit the limits in force");
  }

  uint64_t packed_bytes_max = std::min<uint64_t>(chunk_bytes(chunk_frames, chunk_rows, cpc, chunk_cols), in_cap);
  vk::BufferView packed_x_all = given ? given->input.buffer() : rec.scratch(0, packed_bytes_max, "convolution input chunk (repacked)");
  // One group's weights: packed at load, bound in place where the group takes every input channel and starts
  // aligned; else repacked (from the stored or the packed layout) into the staging.
  auto in_place = [&](int64_t n0) {
    return w.packed() && cc == j.cin && (w.tensor().buffer().offset + uint64_t(n0 * taps * cpc * wb)) % l.align == 0;
  };
  bool staged = false;
  for (int64_t n0 = 0; n0 < j.cout && !staged; n0 += ng) staged = !in_place(n0);
  const uint64_t packed_w_bytes = uint64_t(ng * taps * cpc * wb);
  vk::BufferView packed_w;
  if (staged) {
    packed_w = given ? given->weights.buffer() : rec.scratch(1, packed_w_bytes, "convolution weights (repacked)");
    packed_w.size = packed_w_bytes;
  }

  const int64_t steps = cpc / 8;
  const uint32_t ku = steps % 4 == 0 ? std::min<uint32_t>(4, uint32_t(tile.k_unroll)) : (steps % 2 == 0 ? std::min<uint32_t>(2, uint32_t(tile.k_unroll)) : 1u);
  std::array<uint32_t, 7> gemm_spec = {uint32_t(tile.rows), uint32_t(tile.cols), wdt, uint32_t(tile.lanes),
                                       uint32_t(tile.sg_m), std::max(ku, 1u), bdt};
  std::array<uint32_t, 4> tiled_spec = {uint32_t(tile_m / 16), uint32_t(tile_n / 16), wdt, bdt};
  const bool vec8 = fam.kind == KernelFamily::coopmat && device_tuning(caps).conv_coopmat_vector_loads &&
                    conv_coopmat_vec8_fits(fam.layout, cpc, wdt, j.kh, j.kw, x16);
  const vk::Pipeline& gemm =
      fam.kind == KernelFamily::tiled     ? ctx.pipelines().get("nn/conv_tiled", tiled_spec)
      : fam.kind == KernelFamily::coopmat
          ? coopmat_pipeline(ctx, fam.twin ? "nn/conv_coopmat_twin" : "nn/conv_coopmat",
                             conv_coopmat_spec(fam.layout, wdt,
                                               conv_coopmat_stages(caps, fam.layout,
                                                                   device_tuning(caps).conv_coopmat_double_buffer),
                                               x16, bdt, vec8),
                             fam.twin ? 0u : uint32_t(fam.layout.lanes), conv_coopmat_unfit(caps, fam.layout, fam.twin))
          : ctx.pipelines().get(tile.lanes == 2 ? "nn/conv_gemm_nosubgroup" : "nn/conv_gemm", gemm_spec);
  // The coopmat2 kernel in its place for the chunks it takes (ops_conv_coopmat2.hpp).
  const ConvCoopmat2 cm2 = conv_coopmat2_kernel(ctx, {fam.kind == KernelFamily::coopmat && !fam.twin, x16, cpc, j.stride,
                                                      j.ho, j.wo, j.ys_c, j.ys_h, j.ys_w, wdt, bdt});
  note_kernel(ctx, "conv", fam.twin ? KernelFamily::tiled : fam.kind, gemm.name,
              {fam.kind == KernelFamily::coopmat ? std::string() : device_tuning(caps).conv_unfit, true});
  const vk::BufferView bias_view = conv::bias_binding(x, bias);
  const bool whole_y = uint64_t(y.bytes()) <= l.storage;  // bound whole as before; else per dispatch

  if (cc < j.cin || ng < j.cout || chunk_frames < j.frames_out || chunk_rows < j.ho || chunk_cols < j.wo)
    ctx.note_split(op);  // once per call: the GEMM runs in several chunks
  for_each_chunk(j.cin, cc, [&](int64_t c0, int64_t ncc) {
    for_each_chunk(j.cout, ng, [&](int64_t n0, int64_t nn) {
      vk::BufferView wv = packed_w;
      if (in_place(n0)) {
        wv = w.tensor().buffer();
        wv.offset += uint64_t(n0 * taps * cpc * wb);
        wv.size = uint64_t(nn * taps * cpc * wb);
      } else {
        pack_conv_weight_slice(rec, op, w, n0, nn, c0, ncc, cpc, packed_w);
      }
      for (int64_t b = 0; b < j.b; ++b)
        for_each_chunk(j.frames_out, chunk_frames, [&](int64_t fo0, int64_t nfo) {
          for_each_chunk(j.ho, chunk_rows, [&](int64_t oh0, int64_t nr) {
           for_each_chunk(j.wo, chunk_cols, [&](int64_t ow0, int64_t nc) {
            RowSpan rs = source_rows(j, oh0, oh0 + nr), cs = source_cols(j, ow0, ow0 + nc);
            const int64_t src_rows = std::max<int64_t>(rs.end - rs.first, 0), packed_frames = nfo + j.kt - 1;
            const int64_t src_cols = std::max<int64_t>(cs.end - cs.first, 0);
            const int64_t texels = packed_frames * src_rows * src_cols * (cpc / 4);
            vk::BufferView packed_x = packed_x_all;
            packed_x.size = uint64_t(texels + cpc / 4) * 4 * xb;
            conv::pack_input(rec, op, j, x, l, b, c0, ncc, cpc, fo0, packed_frames, rs.first, src_rows, cs.first,
                             src_cols, x16, packed_x, pack_columns(caps));

            GemmPush pc{};
            const int64_t m = nfo * nr * nc;
            pc.m = u32(op, m);
            pc.n = u32(op, nn);
            pc.cp = u32(op, cpc);
            pc.kt = u32(op, j.kt), pc.kh = u32(op, j.kh), pc.kw = u32(op, j.kw);
            pc.stride = u32(op, j.stride), pc.up = u32(op, up);
            pc.wo = u32(op, nc), pc.rows = u32(op, nr), pc.oh0 = u32(op, oh0);
            pc.ow0 = u32(op, ow0), pc.src_c0 = u32(op, cs.first);
            pc.pad_top = int32_t(j.pad_top), pc.pad_left = int32_t(j.pad_left);
            pc.in_h = u32(op, up * j.h), pc.in_w = u32(op, up * j.w);
            pc.src_r0 = u32(op, rs.first), pc.src_rows = u32(op, src_rows), pc.src_w = u32(op, src_cols);
            pc.zero_texel = u32(op, texels);
            pc.ys_f = u32(op, j.ys_f), pc.ys_h = u32(op, j.ys_h), pc.ys_w = u32(op, j.ys_w), pc.ys_c = u32(op, j.ys_c);
            pc.has_bias = bias ? 1 : 0;
            pc.n_base = u32(op, n0);
            pc.accumulate = c0 > 0 ? 1 : 0;
            const uint64_t y0 = uint64_t(b * j.ys_b + fo0 * j.ys_f + oh0 * j.ys_h + ow0 * j.ys_w + n0 * j.ys_c);
            uint32_t ybase = 0;
            vk::BufferView yv = whole_y ? y.buffer() : aligned_view(y.buffer(), y0 * 4, (y0 + y_span(nn, nfo, nr, nc)) * 4, l.align, 4, ybase);
            pc.y_base = uint32_t(y0) - ybase;
            uint32_t gx = div_up(m, tile_m), gy = div_up(nn, tile_n);
            if (cm2.takes({packed_x.offset, wv.offset, yv.offset + 4 * pc.y_base}, j.ys_f, nfo, nr, nc)) {
              note_kernel(ctx, "conv", KernelFamily::coopmat, cm2.pipe->name);
              rec.dispatch(*cm2.pipe, {packed_x, wv, bias_view, yv}, &pc, sizeof pc, cm2.groups_x(nfo, nr, nc),
                           div_up(nn, cm2.n), 1, op);
            } else if (fam.kind == KernelFamily::texel)
              rec.dispatch(gemm,
                           {vk::Binding(packed_x, VK_FORMAT_R32G32B32A32_SFLOAT),
                            vk::Binding(wv, VK_FORMAT_R32G32B32A32_UINT), bias_view, yv},
                           &pc, sizeof pc, gx, gy, 1, op);
            else
              rec.dispatch(gemm, {packed_x, wv, bias_view, yv}, &pc, sizeof pc, gx, gy, 1, op);
           });
          });
        });
    });
  });
}

// The conv cache update (conv3d_cache.comp) in dispatches over (b, c) planes, elements of one plane and cache
// slots whose x / old cache / new cache parts each fit one binding. Slot j is padded frame F + j: x frame
// F + j - P, or (F + j < P) old slot F + j, or x frame 0 without an old cache.
void record_cache(vk::Recorder& rec, const ConvJob& j, const Tensor& x, const Tensor* cache_in, const Tensor& cache_out) {
  const char* op = "causal_conv3d";
  const ConvLimits l = conv_limits(rec.context().caps());
  const int64_t hw = j.h * j.w, bcs = j.b * j.cin, fr = j.frames, pr = j.prefix;
  const uint64_t cap = l.storage > l.align + 4 ? (l.storage - l.align - 4) / 4 : 0;  // elements per binding
  using Range = std::pair<uint64_t, uint64_t>;
  // Element ranges of x, the old and the new cache that planes [bc0, +nbc) x elements [s0, +ns) x slots [j0, +nj) touch.
  auto ranges = [&](int64_t bc0, int64_t nbc, int64_t s0, int64_t ns, int64_t j0, int64_t nj) {
    int64_t xlo = -1, xhi = -1, plo = -1, phi = -1;
    auto add = [](int64_t& lo, int64_t& hi, int64_t v) { lo = lo < 0 ? v : std::min(lo, v), hi = std::max(hi, v); };
    for (int64_t k = j0; k < j0 + nj; ++k) {
      const int64_t t = fr + k;
      if (t >= pr) add(xlo, xhi, t - pr);
      else if (cache_in) add(plo, phi, t);
      else add(xlo, xhi, 0);
    }
    auto span = [&](int64_t per, int64_t lo, int64_t hi) {
      return lo < 0 ? Range{0, 0} : Range(uint64_t((bc0 * per + lo) * hw + s0), uint64_t(((bc0 + nbc - 1) * per + hi) * hw + s0 + ns));
    };
    return std::array<Range, 3>{span(fr, xlo, xhi), span(pr, plo, phi), span(pr, j0, j0 + nj - 1)};
  };
  auto fits = [&](int64_t nbc, int64_t ns, int64_t nj) {
    for (int64_t j0 = 0; j0 + nj <= pr; j0 += nj)
      for (const Range& r : ranges(0, nbc, 0, ns, j0, nj))
        if (r.second - r.first > cap) return false;
    return uint64_t(nbc * ns) <= l.groups_1d * 64;
  };
  int64_t nbc = bcs, ns = hw, nj = pr;
  if (!fits(nbc, ns, nj)) {
    nbc = std::max<int64_t>(1, int64_t(cap / uint64_t(std::max(fr, pr) * hw)));
    while (nbc > 1 && !fits(nbc, ns, nj)) --nbc;
    if (!fits(nbc, ns, nj)) nj = 1;
    while (ns > 1 && !fits(nbc, ns, nj)) ns = (ns + 1) / 2;
    expect(fits(nbc, ns, nj), op, "the conv cache of one plane element exceeds one binding");
  }
  std::array<uint32_t, 1> spec = {kMaxCachePrefix};
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/conv3d_cache", spec);
  if (nbc < bcs || ns < hw || nj < pr) rec.context().note_split("conv cache");
  for_each_chunk(bcs, nbc, [&](int64_t bc0, int64_t nb) {
    for_each_chunk(pr, nj, [&](int64_t j0, int64_t njs) {
      for_each_chunk(hw, ns, [&](int64_t s0, int64_t n) {
        struct {
          uint32_t columns, hw, frames, prefix, use_prev, bc0, s0, ns, x_base, prev_base, next_base, j0, nj;
        } pc{u32(op, nb * n), u32(op, hw), u32(op, fr), u32(op, pr), cache_in ? 1u : 0u, u32(op, bc0), u32(op, s0),
             u32(op, n), 0, 0, 0, u32(op, j0), u32(op, njs)};
        auto r = ranges(bc0, nb, s0, n, j0, njs);
        for (Range& q : r)
          if (q.second == q.first) q = {0, 1};  // not read: any valid view
        vk::BufferView xv = aligned_view(x.buffer(), r[0].first * 4, r[0].second * 4, l.align, 4, pc.x_base);
        vk::BufferView nv = aligned_view(cache_out.buffer(), r[2].first * 4, r[2].second * 4, l.align, 4, pc.next_base);
        vk::BufferView pv = cache_in ? aligned_view(cache_in->buffer(), r[1].first * 4, r[1].second * 4, l.align, 4, pc.prev_base) : xv;
        if (!cache_in) pc.prev_base = pc.x_base;
        Grid g = grid_1d(rec.context().caps(), nb * n, 64);
        rec.dispatch(pipe, {xv, pv, nv}, &pc, sizeof pc, g.x, g.y, 1, "causal_conv3d_cache");
      });
    });
  });
}

// Weight shape as (Cout, Cin, kt, kh, kw) from a 4-D or 5-D tensor.
std::array<int64_t, 5> kernel_dims(const char* op, const ConvWeights& w) {
  const Shape& s = w.shape();
  if (s.size() == 5) return {s[0], s[1], s[2], s[3], s[4]};
  if (s.size() == 4) return {s[0], s[1], 1, s[2], s[3]};
  if (s.size() == 2) return {s[0], s[1], 1, 1, 1};
  fail(op, "weights " + w.describe() + " must be [Cout, Cin, (kt,) kh, kw]");
}

}  // namespace

void set_conv_register_block(const ConvRegisterBlock& block) {
  if (block.rows < 0 || block.rows > 16 || block.cols < 0 || block.cols > 8 || block.lanes > 2 ||
      !(block.k_unroll == 0 || block.k_unroll == 1 || block.k_unroll == 2 || block.k_unroll == 4) || block.pack_columns < 0)
    fail("set_conv_register_block",
         "block out of range (rows 1..16, cols 1..8, lanes -1..2, k_unroll 0, 1, 2, 4, pack_columns >= 0)");
  g_block_override = block;
}

void set_conv_chunk_bytes(uint64_t bytes) { g_chunk_bytes_override = bytes; }

DType conv_weight_dtype(const vk::DeviceCaps& caps) {
  return conv_family(caps).kind == KernelFamily::coopmat && device_tuning(caps).conv_weights_fp16 ? DType::f16
                                                                                                   : DType::bf16;
}

DType conv_repack_dtype(const vk::DeviceCaps& caps) {
  return conv_family(caps).kind == KernelFamily::coopmat && device_tuning(caps).conv_activations_fp16 ? DType::f16
                                                                                                       : DType::f32;
}

Shape conv2d_shape(const Shape& x, const Shape& w, const Conv2dParams& p) {
  const char* op = "conv2d";
  expect(x.size() == 4 || x.size() == 5, op, "input must be [N, C, H, W] or [B, C, F, H, W], got [" + shape_str(x) + "]");
  expect(w.size() == 4 || (w.size() == 5 && w[2] == 1), op, "weights must be [Cout, Cin, kh, kw], got [" + shape_str(w) + "]");
  int64_t kh = w[w.size() - 2], kw = w[w.size() - 1];
  int64_t h = x[x.size() - 2], wd = x[x.size() - 1];
  expect(p.stride >= 1, op, "stride must be >= 1");
  int64_t hp = h + p.pad_top + p.pad_bottom, wp = wd + p.pad_left + p.pad_right;
  expect(hp >= kh && wp >= kw, op, "padded input smaller than the kernel");
  int64_t ho = (hp - kh) / p.stride + 1, wo = (wp - kw) / p.stride + 1;
  int64_t cout = w[0];
  if (x.size() == 4) return p.channels_last_out ? Shape{x[0], ho, wo, cout} : Shape{x[0], cout, ho, wo};
  return p.channels_last_out ? Shape{x[0], x[2], ho, wo, cout} : Shape{x[0], cout, x[2], ho, wo};
}

void conv2d(vk::Recorder& rec, const Tensor& x, const ConvWeights& w, const Tensor* bias, const Tensor& y,
            const Conv2dParams& p, const ConvScratch* scratch) {
  const char* op = "conv2d";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect_shape(op, "y", y, conv2d_shape(x.shape(), w.shape(), p));
  auto k = kernel_dims(op, w);
  ConvJob j;
  if (x.rank() == 4) {
    j.b = x.dim(0), j.cin = x.dim(1), j.frames = 1, j.h = x.dim(2), j.w = x.dim(3);
  } else {
    j.b = x.dim(0), j.cin = x.dim(1), j.frames = x.dim(2), j.h = x.dim(3), j.w = x.dim(4);
  }
  expect(k[1] == j.cin, op, "weights " + w.describe() + " do not match input channels of " + x.describe());
  j.cout = k[0], j.kt = 1, j.kh = k[3], j.kw = k[4], j.stride = p.stride;
  j.pad_top = p.pad_top, j.pad_left = p.pad_left;
  expect(p.pad_top >= 0 && p.pad_left >= 0 && p.pad_bottom >= 0 && p.pad_right >= 0, op, "negative padding");
  j.ho = (j.h + p.pad_top + p.pad_bottom - j.kh) / p.stride + 1;
  j.wo = (j.w + p.pad_left + p.pad_right - j.kw) / p.stride + 1;
  j.frames_out = j.frames, j.prefix = 0;
  int64_t plane = j.ho * j.wo;
  if (p.channels_last_out) {
    j.ys_w = j.cout, j.ys_h = j.wo * j.cout, j.ys_c = 1, j.ys_f = plane * j.cout, j.ys_b = j.frames * plane * j.cout;
  } else {
    j.ys_w = 1, j.ys_h = j.wo, j.ys_f = plane, j.ys_c = j.frames * plane, j.ys_b = j.cout * j.frames * plane;
  }
  check_bias(op, bias, j.cout);
  record_conv(rec, op, j, x, w, bias, y, scratch);
}

Shape causal_conv3d_cache_shape(const Shape& x, const Shape& w) {
  expect(x.size() == 5 && w.size() == 5, "causal_conv3d", "cache shape needs 5-D input and weights");
  return {x[0], x[1], w[2] - 1, x[3], x[4]};
}

void causal_conv3d(vk::Recorder& rec, const Tensor& x, const ConvWeights& w, const Tensor* bias, const Tensor& y,
                   const Tensor* cache_in, const Tensor* cache_out, const ConvScratch* scratch) {
  const char* op = "causal_conv3d";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect(x.rank() == 5, op, "input must be [B, C, F, H, W], got " + x.describe());
  auto k = kernel_dims(op, w);
  ConvJob j;
  j.b = x.dim(0), j.cin = x.dim(1), j.frames = x.dim(2), j.h = x.dim(3), j.w = x.dim(4);
  expect(k[1] == j.cin, op, "weights " + w.describe() + " do not match input channels of " + x.describe());
  j.cout = k[0], j.kt = k[2], j.kh = k[3], j.kw = k[4], j.stride = 1;
  expect(j.kh % 2 == 1 && j.kw % 2 == 1 && j.kt >= 1, op, "kernel " + w.describe() + " must have odd kh, kw");
  j.pad_top = (j.kh - 1) / 2, j.pad_left = (j.kw - 1) / 2;
  j.ho = j.h, j.wo = j.w, j.frames_out = j.frames, j.prefix = j.kt - 1;
  expect_shape(op, "y", y, {j.b, j.cout, j.frames, j.h, j.w});
  expect(j.prefix <= int64_t(kMaxCachePrefix), op, "time kernel too long");
  Shape cache_shape = {j.b, j.cin, j.prefix, j.h, j.w};
  if (j.prefix == 0) expect(!cache_in && !cache_out, op, "a kt = 1 convolution has no cache");
  if (cache_in) {
    expect_dtype(op, "cache_in", *cache_in, DType::f32);
    expect_shape(op, "cache_in", *cache_in, cache_shape);
  }
  if (cache_out) {
    expect_dtype(op, "cache_out", *cache_out, DType::f32);
    expect_shape(op, "cache_out", *cache_out, cache_shape);
  }
  int64_t plane = j.h * j.w;
  j.ys_w = 1, j.ys_h = j.w, j.ys_f = plane, j.ys_c = j.frames * plane, j.ys_b = j.cout * j.frames * plane;
  check_bias(op, bias, j.cout);
  // The prefix replicates frame 0 (first frame batch) or is the previous batch's cache; either way the
  // taps are summed in the same order, so a clip run in frame batches equals the whole clip bit for bit.
  j.time_mode = cache_in ? 3 : 0;
  j.cache = cache_in;
  record_conv(rec, op, j, x, w, bias, y, scratch);

  if (cache_out && j.frames > 0) record_cache(rec, j, x, cache_in, *cache_out);
}

void conv1x1(vk::Recorder& rec, const Tensor& x, const ConvWeights& w, const Tensor* bias, const Tensor& y,
             const ConvScratch* scratch) {
  const char* op = "conv1x1";
  auto k = kernel_dims(op, w);
  expect(k[2] == 1 && k[3] == 1 && k[4] == 1, op, "weights " + w.describe() + " are not 1x1x1");
  expect(x.rank() == 5, op, "input must be [B, C, F, H, W], got " + x.describe());
  causal_conv3d(rec, x, w, bias, y, nullptr, nullptr, scratch);  // kernel_dims reads [Cout, Cin] as 1x1x1
}


void upsample2x_conv3x3(vk::Recorder& rec, const Tensor& x, const ConvWeights& w, const Tensor* bias, const Tensor& y,
                        bool compress_time, const ConvScratch* scratch) {
  const char* op = "upsample2x_conv3x3";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  Shape up = upsample2x_shape(x.shape(), compress_time);
  auto k = kernel_dims(op, w);
  expect(k[2] == 1 && k[3] == 3 && k[4] == 3 && k[1] == x.dim(1), op,
         "weights " + w.describe() + " must be [Cout, " + std::to_string(x.dim(1)) + ", 3, 3]");
  expect_shape(op, "y", y, {up[0], k[0], up[2], up[3], up[4]});
  ConvJob j;
  j.b = x.dim(0), j.cin = x.dim(1), j.frames = x.dim(2), j.h = x.dim(3), j.w = x.dim(4);
  j.cout = k[0], j.kt = 1, j.kh = 3, j.kw = 3, j.stride = 1, j.pad_top = 1, j.pad_left = 1;
  j.ho = up[3], j.wo = up[4], j.frames_out = up[2], j.prefix = 0;
  j.upsample = true;
  int64_t f = x.dim(2);
  j.time_mode = !compress_time || f <= 1 ? 0 : (f % 2 == 1 ? 1 : 2);
  int64_t plane = j.ho * j.wo;
  j.ys_w = 1, j.ys_h = j.wo, j.ys_f = plane, j.ys_c = j.frames_out * plane, j.ys_b = j.cout * j.frames_out * plane;
  check_bias(op, bias, j.cout);
  record_conv(rec, op, j, x, w, bias, y, scratch);
}

ConvScratchSize conv2d_scratch(const Shape& x, const Shape& w) {
  expect(x.size() == 4 || x.size() == 5, "conv2d", "input must be [N, C, H, W] or [B, C, F, H, W]");
  int64_t frames = x.size() == 5 ? x[2] : 1;
  return scratch_size(frames, 1, x[x.size() - 2], x[x.size() - 1], x[1], w[0], w[w.size() - 2] * w[w.size() - 1]);
}

ConvScratchSize causal_conv3d_scratch(const Shape& x, const Shape& w) {
  expect(x.size() == 5, "causal_conv3d", "input must be [B, C, F, H, W]");
  int64_t kt = w.size() == 5 ? w[2] : 1, taps = 1;
  for (size_t i = 2; i < w.size(); ++i) taps *= w[i];
  return scratch_size(x[2], kt, x[3], x[4], x[1], w[0], taps);
}

ConvScratchSize upsample2x_conv3x3_scratch(const Shape& x, const Shape& w, bool compress_time) {
  Shape up = upsample2x_shape(x, compress_time);
  return scratch_size(up[2], 1, x[3], x[4], x[1], w[0], 9);
}

}  // namespace dvs::ops
