#include "tensor/ops_conv_pack.hpp"

#include <algorithm>
#include <array>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "tensor/kernel_tuning.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops::conv {
namespace {

// Source frame of packed (time-padded) frame tp, and whether it comes from the cache (conv_pack_input.comp).
std::pair<int64_t, bool> source_frame(const ConvJob& j, int64_t tp) {
  switch (j.time_mode) {
    case 1: return {tp == 0 ? 0 : 1 + (tp - 1) / 2, false};
    case 2: return {tp / 2, false};
    case 3: return tp < j.prefix ? std::pair<int64_t, bool>{tp, true} : std::pair<int64_t, bool>{tp - j.prefix, false};
    default: return {std::max<int64_t>(tp - j.prefix, 0), false};
  }
}

// Elements [first, end) of x (cache = false) or of the cache that packing chunk channels [ca, cb) (absolute
// channels), padded frames [tpa, tpb), source rows [r0, r0 + rows) and columns [col0, col0 + wc) reads;
// empty: {0, 0}.
std::pair<uint64_t, uint64_t> pack_reads(const ConvJob& j, bool cache, int64_t b, int64_t ca, int64_t cb, int64_t tpa,
                                         int64_t tpb, int64_t r0, int64_t rows, int64_t col0, int64_t wc) {
  int64_t lo = -1, hi = -1;
  for (int64_t tp = tpa; tp < tpb; ++tp) {
    auto [f, from_cache] = source_frame(j, tp);
    if (from_cache != cache) continue;
    lo = lo < 0 ? f : std::min(lo, f);
    hi = std::max(hi, f);
  }
  if (lo < 0 || rows == 0 || wc == 0) return {0, 0};
  const int64_t frames = cache ? j.prefix : j.frames, hw = j.h * j.w;
  uint64_t first = uint64_t(((b * j.cin + ca) * frames + lo) * hw + r0 * j.w + col0);
  uint64_t end = uint64_t(((b * j.cin + cb - 1) * frames + hi) * hw + (r0 + rows - 1) * j.w + col0 + wc);
  return {first, end};
}

struct PackInputPush {
  uint32_t cp4, c, src_frames, h, w, batch, tp0, frames, r0, rows, prefix, time_mode;
  uint32_t c0, cc, q0, nq, ca, cb, c4a, nc4, x_base, cache_base, zero, partial, col0, wc, seg;
  uint32_t halo_top, rows_p, halo_left, cols_p, up_shift;
};
static_assert(sizeof(PackInputPush) <= 128);

}  // namespace

void pack_input(vk::Recorder& rec, const char* op, const ConvJob& j, const Tensor& x, const ConvLimits& l, int64_t b,
                int64_t c0, int64_t cc, int64_t cpc, int64_t tp0, int64_t nframes, int64_t r0, int64_t rows,
                int64_t col0, int64_t wc, bool f16, const vk::BufferView& packed, int64_t pack_columns,
                const PackGrid& grid) {
  // The packed grid: the source rows and columns alone, or with their halo.
  const int64_t rows_p = grid.rows_p ? grid.rows_p : rows, cols_p = grid.cols_p ? grid.cols_p : wc;
  expect(grid.halo_top >= 0 && grid.halo_top + rows <= rows_p && grid.halo_left >= 0 && grid.halo_left + wc <= cols_p,
         op, "the packed grid does not hold its source rows and columns");
  expect(grid.up == 1 || grid.up == 2, op, "upsampling by " + std::to_string(grid.up));
  // The rows and columns of x itself that the grid's (upsampled) ones read: what the views must hold. (Plain
  // variables, not a structured binding: the lambdas below capture them, which clang's C++20 refuses for bindings.)
  auto source_count = [&](int64_t first, int64_t n) {
    return n == 0 ? int64_t(0) : (first + n - 1) / grid.up - first / grid.up + 1;
  };
  const int64_t src_r0 = r0 / grid.up, src_rows = source_count(r0, rows);
  const int64_t src_col0 = col0 / grid.up, src_wc = source_count(col0, wc);
  const int64_t cp4 = cpc / 4;
  const uint64_t cap = l.r32;  // bytes of one R32F view
  const int64_t seg = pack_columns > 0 && pack_columns < cols_p ? pack_columns : cols_p;  // pixels per invocation
  const int64_t nseg = (cols_p + seg - 1) / seg;
  auto fits = [&](int64_t ca, int64_t cb, int64_t qa, int64_t qb) {
    for (bool cache : {false, true}) {
      auto [first, end] = pack_reads(j, cache, b, c0 + ca, c0 + cb, tp0 + qa, tp0 + qb, src_r0, src_rows, src_col0,
                                     src_wc);
      if ((end - first) * 4 + l.align > cap) return false;
    }
    int64_t c4a = ca / 4, c4b = cb == cc ? cp4 : (cb + 3) / 4;
    return uint64_t((qb - qa) * rows_p * nseg * (c4b - c4a) + cp4) <= l.groups_1d * 64;
  };
  // Every chunk must fit, not only the first: with the causal prefix the first frames all read frame 0
  // (a small span), later ones read as many frames as they pack.
  auto fits_all = [&](int64_t nc, int64_t nq) {
    for (int64_t qa = 0; qa < nframes; qa += nq)
      for (int64_t ca = 0; ca < cc; ca += nc)
        if (!fits(ca, std::min(ca + nc, cc), qa, std::min(qa + nq, nframes))) return false;
    return true;
  };
  int64_t nc = cc, nq = nframes;
  while (nc > 1 && !fits_all(nc, nq)) --nc;
  while (nq > 1 && !fits_all(nc, nq)) --nq;
  expect(fits_all(nc, nq), op, "one source row of one channel exceeds one texel view");
  const vk::DeviceCaps& caps = rec.context().caps();
  const DeviceTuning& tuning = device_tuning(caps);
  const std::array<uint32_t, 2> spec = {f16 ? 1u : 0u, tuning.conv_pack_pixel_major ? 1u : 0u};
  bool zero = true;
  for_each_chunk(nframes, nq, [&](int64_t qa, int64_t q) {
    for_each_chunk(cc, nc, [&](int64_t ca, int64_t n) {
      const int64_t cb = ca + n, c4a = ca / 4, c4b = cb == cc ? cp4 : (cb + 3) / 4;
      const bool partial = ca % 4 != 0 || (cb % 4 != 0 && cb != cc);
      PackInputPush pp{u32(op, cp4), u32(op, j.cin), u32(op, j.frames), u32(op, j.h), u32(op, j.w),
                       u32(op, b), u32(op, tp0), u32(op, nframes), u32(op, r0), u32(op, rows), u32(op, j.prefix),
                       j.time_mode, u32(op, c0), u32(op, cc), u32(op, qa), u32(op, q), u32(op, ca), u32(op, cb),
                       u32(op, c4a), u32(op, c4b - c4a), 0, 0, zero ? 1u : 0u,
                       partial ? 1u : 0u, u32(op, col0), u32(op, wc),
                       u32(op, seg), u32(op, grid.halo_top), u32(op, rows_p), u32(op, grid.halo_left),
                       u32(op, cols_p), grid.up == 2 ? 1u : 0u};
      // x and the cache as R32F sub-views; a tensor this dispatch does not read is bound as x's first texels.
      vk::BufferView views[2];
      for (int k = 0; k < 2; ++k) {
        const Tensor& t = k == 1 && j.cache ? *j.cache : x;
        auto [first, end] = pack_reads(j, k == 1, b, c0 + ca, c0 + cb, tp0 + qa, tp0 + qa + q, src_r0, src_rows,
                                       src_col0, src_wc);
        if (end == first) first = 0, end = 4;
        views[k] = aligned_view(t.buffer(), first * 4, end * 4, l.align, 4, k == 0 ? pp.x_base : pp.cache_base);
      }
      const std::vector<vk::Binding> bindings = {vk::Binding(views[0], VK_FORMAT_R32_SFLOAT),
                                                 vk::Binding(views[1], VK_FORMAT_R32_SFLOAT), packed};
      // The transposing kernel: tiles of 32 channels x 64 columns of a packed row, a workgroup each, and one for the
      // zero pixel. Where a dispatch merges channels into vec4s others wrote, or its tiles exceed the grid, the other.
      const int64_t tiles = q * rows_p * ((cols_p + 63) / 64) * ((c4b - c4a + 7) / 8) + (zero ? 1 : 0);
      if (tuning.conv_pack_tiled && !partial && uint64_t(tiles) <= l.groups_1d) {
        const Grid g = grid_1d(caps, tiles, 1);
        rec.dispatch(rec.context().pipelines().get("nn/conv_pack_input_tiled", std::span(spec).first(1)), bindings, &pp,
                     sizeof pp, g.x, g.y, 1, std::string(op) + "_pack_input");
      } else {
        const Grid g = grid_1d(caps, int64_t(q * rows_p * nseg * (c4b - c4a)) + (zero ? cp4 : 0), 64);
        rec.dispatch(rec.context().pipelines().get("nn/conv_pack_input", spec), bindings, &pp, sizeof pp, g.x, g.y, 1,
                     std::string(op) + "_pack_input");
      }
      zero = false;
    });
  });
}

}  // namespace dvs::ops::conv
