#include "tensor/ops_layout.hpp"

#include <algorithm>
#include <numeric>
#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

constexpr uint32_t kLocal = 64, kMaxGroups = 4096;

// Shaders here loop grid-stride over x (and rows over y): fewer groups than the limit allows just loop more.
uint32_t groups_for(const vk::DeviceCaps& caps, int64_t items) {
  return std::clamp<uint32_t>(div_up(items, kLocal), 1, std::min(kMaxGroups, caps.max_workgroup_count[0]));
}

// Grid for shaders that loop rows over y and a row's items over x (grid-stride both): x covers a row,
// y as many rows as keep the total near kMaxGroups groups.
// Rows shorter than kLaneRows items go one whole row per invocation over x instead (lane_rows), so that a
// 64-wide group is not spent on a row of 1 to 31 items.
constexpr int64_t kLaneRows = 32;
struct Grid2 {
  uint32_t x, y, lane_rows;
};
Grid2 grid_rows(const vk::DeviceCaps& caps, int64_t rows, int64_t row_items) {
  if (row_items < kLaneRows) return {groups_for(caps, rows), 1, 1};
  // Up to 16 items per invocation and row: per-row set-up (permute's index decomposition) is amortised.
  const uint32_t gx = groups_for(caps, div_up(row_items, 16));
  const int64_t gy = std::clamp<int64_t>(rows, 1, std::max<int64_t>(1, kMaxGroups / gx));
  return {gx, uint32_t(std::min<int64_t>(gy, caps.max_workgroup_count[1])), 0};
}

[[noreturn]] void fail(const char* op, const std::string& why) { throw Error(std::string("internal: ") + op + ": " + why); }

void check_words(const char* op, const Tensor& t) {
  if (dtype_size(t.dtype()) != 4) fail(op, t.describe() + ": only 4-byte element types (f32, i32) are supported");
  if (t.numel() >= int64_t(UINT32_MAX) - 4) fail(op, t.describe() + " is too large");
}

int norm_axis(const char* op, int axis, size_t rank) {
  int r = int(rank);
  if (axis < 0) axis += r;
  if (axis < 0 || axis >= r) fail(op, "axis out of range for rank " + std::to_string(rank));
  return axis;
}

// One strided 2-D copy of words: dst[dst_off + r·dst_stride + k] = src[src_off + r·src_stride + k].
struct Copy2d {
  int64_t rows, len, src_stride, src_off, dst_stride, dst_off;
};

void record_copy2d(vk::Recorder& rec, const vk::BufferView& src, const vk::BufferView& dst, Copy2d c, const char* label) {
  if (c.rows == 0 || c.len == 0) return;
  const bool vec4 = c.len % 4 == 0 && c.src_stride % 4 == 0 && c.src_off % 4 == 0 && c.dst_stride % 4 == 0 &&
                    c.dst_off % 4 == 0;
  const int64_t q = vec4 ? 4 : 1;
  const Grid2 g = grid_rows(rec.context().caps(), c.rows, c.len / q);
  vk::Context& ctx = rec.context();
  const bool texel = vec4 && texel_inputs(ctx.caps()) && texel_view_ok(ctx, src, 16);
  struct {
    uint32_t rows, len, src_stride, src_off, dst_stride, dst_off, lane_rows;
  } push{uint32_t(c.rows), uint32_t(c.len / q), uint32_t(c.src_stride / q), uint32_t(c.src_off / q),
         uint32_t(c.dst_stride / q), uint32_t(c.dst_off / q), g.lane_rows};
  const char* shader = texel ? "nn/concat_copy_tex4" : vec4 ? "nn/concat_copy_vec4" : "nn/concat_copy";
  const vk::Pipeline& p = ctx.pipelines().get(shader);
  const vk::Binding in = texel ? vk::Binding(src, VK_FORMAT_R32G32B32A32_UINT) : vk::Binding(src);
  rec.dispatch(p, {in, dst}, &push, sizeof push, g.x, g.y, 1, label);
}

// The words [first, end) of `v` bound from the aligned-down start: the view and the offset of `first` in it.
std::pair<vk::BufferView, int64_t> word_window(const vk::BufferView& v, int64_t first, int64_t end,
                                               int64_t align_words) {
  const int64_t base = first / align_words * align_words;
  return {v.sub(VkDeviceSize(base) * 4, VkDeviceSize(end - base) * 4), first - base};
}

// record_copy2d in pieces whose source and destination windows each fit one binding: blocks of whole rows,
// and rows longer than a binding in column pieces. Windows start aligned down, the offsets go to the shader.
// Returns whether it took more than one window (the caller notes its op's split once).
bool copy2d(vk::Recorder& rec, const vk::BufferView& src, const vk::BufferView& dst, Copy2d c, const char* label) {
  const vk::DeviceCaps& caps = rec.context().caps();
  const uint64_t cap = binding_capacity(caps, 0);
  if (c.rows == 0 || c.len == 0) return false;
  if (src.size <= cap && dst.size <= cap) {
    record_copy2d(rec, src, dst, c, label);
    return false;
  }
  const int64_t align = int64_t(binding_alignment(caps) / 4), room = int64_t(cap / 4) - align;
  // Column pieces: multiples of 4 words keep the vec4 shader where the whole copy has it.
  int64_t cols = std::min(c.len, room / 4 * 4);
  const int64_t stride = std::max(c.src_stride, c.dst_stride);
  const int64_t rows = cols < c.len || stride == 0 ? 1 : std::max<int64_t>(1, 1 + (room - cols) / stride);
  if (cols <= 0) fail(label, "a binding of " + std::to_string(cap) + " bytes cannot hold one aligned piece");
  for_each_chunk(c.rows, rows, [&](int64_t r0, int64_t nr) {
    for_each_chunk(c.len, cols, [&](int64_t k0, int64_t nk) {
      const int64_t s0 = c.src_off + r0 * c.src_stride + k0, d0 = c.dst_off + r0 * c.dst_stride + k0;
      const auto [sv, so] = word_window(src, s0, s0 + (nr - 1) * c.src_stride + nk, align);
      const auto [dv, dof] = word_window(dst, d0, d0 + (nr - 1) * c.dst_stride + nk, align);
      record_copy2d(rec, sv, dv, Copy2d{nr, nk, c.src_stride, so, c.dst_stride, dof}, label);
    });
  });  return rows < c.rows || cols < c.len;
}

// Shared by concat and split: `whole` is cut along `axis` into `parts`.
void bands(vk::Recorder& rec, const char* op, const Tensor& whole, const std::vector<Tensor>& parts, int axis,
           bool into_whole) {
  if (parts.empty()) fail(op, "no tensors");
  const size_t rank = whole.rank();
  axis = norm_axis(op, axis, rank);
  const size_t es = dtype_size(whole.dtype());
  if (es != 4 && es != 2) fail(op, whole.describe() + ": unsupported element type");
  if (whole.numel() >= int64_t(UINT32_MAX) - 4) fail(op, whole.describe() + " is too large");
  int64_t outer = 1, inner = 1, total = 0;
  for (int d = 0; d < axis; ++d) outer *= whole.shape()[size_t(d)];
  for (size_t d = size_t(axis) + 1; d < rank; ++d) inner *= whole.shape()[d];
  for (const Tensor& t : parts) {
    if (t.dtype() != whole.dtype() || t.rank() != rank) fail(op, t.describe() + " does not match " + whole.describe());
    for (size_t d = 0; d < rank; ++d)
      if (int(d) != axis && t.shape()[d] != whole.shape()[d])
        fail(op, t.describe() + " differs from " + whole.describe() + " outside axis " + std::to_string(axis));
    total += t.shape()[size_t(axis)];
  }
  if (total != whole.shape()[size_t(axis)])
    fail(op, "sizes along axis " + std::to_string(axis) + " add up to " + std::to_string(total) + ", not " +
                 std::to_string(whole.shape()[size_t(axis)]));
  const int64_t row = total * inner;
  int64_t offset = 0;
  bool split = false;
  for (const Tensor& t : parts) {
    const int64_t len = t.shape()[size_t(axis)] * inner;
    Copy2d c = into_whole ? Copy2d{outer, len, len, 0, row, offset} : Copy2d{outer, len, row, offset, len, 0};
    offset += len;
    if (es == 2) {
      if (c.len % 2 || c.src_stride % 2 || c.dst_stride % 2 || c.src_off % 2 || c.dst_off % 2)
        fail(op, "16-bit tensors need every band to hold an even number of elements");
      c = {c.rows, c.len / 2, c.src_stride / 2, c.src_off / 2, c.dst_stride / 2, c.dst_off / 2};
    }
    split |= into_whole ? copy2d(rec, t.buffer(), whole.buffer(), c, op) : copy2d(rec, whole.buffer(), t.buffer(), c, op);
  }
  if (split) rec.context().note_split(op);
}

// Output axes as (size, input stride), outermost first, after merging.
using Axes = std::vector<std::pair<int64_t, int64_t>>;

// One permute dispatch: the output (contiguous from word out_off of `out`) of input words read from in_off.
void record_permute(vk::Recorder& rec, const char* op, const vk::BufferView& in, const vk::BufferView& out,
                    const Axes& axes, int64_t in_off, int64_t out_off) {
  int64_t n = 1;
  bool vec4 = axes.back().second == 1 && axes.back().first % 4 == 0 && in_off % 4 == 0 && out_off % 4 == 0;
  for (const auto& a : axes) {
    n *= a.first;
    vec4 = vec4 && (a.second == 1 || a.second % 4 == 0);
  }
  const int64_t q = vec4 ? 4 : 1;
  struct {
    uint32_t rows, rank, dims[6], in_stride[6], lane_rows, in_off, out_off;
  } push{};
  push.rank = uint32_t(axes.size());
  for (size_t d = 0; d < 6; ++d) {
    push.dims[d] = 1;
    push.in_stride[d] = 0;
  }
  for (size_t d = 0; d < axes.size(); ++d) {
    push.dims[d] = uint32_t(axes[d].first);
    push.in_stride[d] = uint32_t(axes[d].second);
  }
  if (vec4) {
    push.dims[axes.size() - 1] /= 4;
    for (size_t d = 0; d < axes.size(); ++d) push.in_stride[d] = d + 1 == axes.size() ? 1 : push.in_stride[d] / 4;
  }
  push.in_off = uint32_t(in_off / q);
  push.out_off = uint32_t(out_off / q);
  const uint32_t last = push.dims[axes.size() - 1];
  push.rows = uint32_t(n / axes.back().first);
  vk::Context& ctx = rec.context();
  const bool texel = vec4 && texel_inputs(ctx.caps()) && texel_view_ok(ctx, in, 16);
  const char* shader = texel ? "nn/permute_tex4" : vec4 ? "nn/permute_vec4" : "nn/permute";
  const vk::Pipeline& p = ctx.pipelines().get(shader);
  const Grid2 g = grid_rows(ctx.caps(), push.rows, last);
  push.lane_rows = g.lane_rows;
  const vk::Binding src = texel ? vk::Binding(in, VK_FORMAT_R32G32B32A32_UINT) : vk::Binding(in);
  rec.dispatch(p, {src, out}, &push, sizeof push, g.x, g.y, 1, op);
}

// A permute too large for one binding: the output is cut into blocks along output axis k (all axes before it
// fixed, nj indices of it, all after it whole), k the outermost axis whose one-index block fits one binding
// on both sides (the input span of a block: its strided extent), at worst the last axis. Windows start
// aligned down; offsets go to the shader.
void permute_split(vk::Recorder& rec, const char* op, const vk::BufferView& in, const vk::BufferView& out,
                   const Axes& axes) {
  const vk::DeviceCaps& caps = rec.context().caps();
  const uint64_t cap = binding_capacity(caps, 0);
  if (in.size <= cap && out.size <= cap) return record_permute(rec, op, in, out, axes, 0, 0);
  rec.context().note_split(op);
  const int64_t align = std::lcm<int64_t>(int64_t(binding_alignment(caps) / 4), 4), room = int64_t(cap / 4) - align;
  const int64_t R = int64_t(axes.size());
  // k = R-1 (pieces of one output row) always fits; a transpose whose rows read far apart ends there.
  int64_t k = R - 1, block = 1, span = 1;  // block: output words per index of axis k; span: their input extent
  for (int64_t c = R - 2; c >= 0; --c) {
    int64_t b = 1, s = 1;
    for (int64_t d = c + 1; d < R; ++d) {
      b *= axes[size_t(d)].first;
      s += (axes[size_t(d)].first - 1) * axes[size_t(d)].second;
    }
    if (b > room || s > room) break;
    k = c, block = b, span = s;
  }
  const int64_t size_k = axes[size_t(k)].first, stride_k = axes[size_t(k)].second;
  int64_t nj = std::min(size_k, room / block);
  if (stride_k > 0) nj = std::min(nj, 1 + (room - span) / stride_k);
  if (k == R - 1 && nj >= 4) nj = nj / 4 * 4;  // row pieces of whole vec4s where the row allows them
  int64_t prefixes = 1;
  for (int64_t d = 0; d < k; ++d) prefixes *= axes[size_t(d)].first;
  for (int64_t pf = 0; pf < prefixes; ++pf) {
    int64_t in_base = 0, rest = pf;
    for (int64_t d = k - 1; d >= 0; --d) {
      in_base += rest % axes[size_t(d)].first * axes[size_t(d)].second;
      rest /= axes[size_t(d)].first;
    }
    for_each_chunk(size_k, nj, [&](int64_t j0, int64_t cnt) {
      const int64_t i0 = in_base + j0 * stride_k, i1 = i0 + (cnt - 1) * stride_k + span;
      const int64_t o0 = (pf * size_k + j0) * block, o1 = o0 + cnt * block;
      const int64_t ib = i0 / align * align, ob = o0 / align * align;
      Axes sub = {{cnt, stride_k}};
      sub.insert(sub.end(), axes.begin() + k + 1, axes.end());
      record_permute(rec, op, in.sub(VkDeviceSize(ib) * 4, VkDeviceSize(i1 - ib) * 4),
                     out.sub(VkDeviceSize(ob) * 4, VkDeviceSize(o1 - ob) * 4), sub, i0 - ib, o0 - ob);
    });
  }
}

// Permute of 4-byte words given the input shape and perm; `out` already checked to hold the result.
void permute_words(vk::Recorder& rec, const char* op, const vk::BufferView& in, const vk::BufferView& out,
                   const Shape& shape, const std::vector<int>& perm) {
  const size_t r = shape.size();
  if (perm.size() != r) fail(op, "permutation of length " + std::to_string(perm.size()) + " for rank " + std::to_string(r));
  std::vector<int64_t> in_stride(r, 1);
  for (size_t d = r; d-- > 1;) in_stride[d - 1] = in_stride[d] * shape[d];
  std::vector<bool> seen(r, false);
  // Output axes as (size, input stride), size-1 axes dropped, then runs that stay contiguous merged.
  Axes axes;
  for (size_t d = 0; d < r; ++d) {
    const int a = perm[d];
    if (a < 0 || size_t(a) >= r || seen[size_t(a)]) fail(op, "invalid permutation");
    seen[size_t(a)] = true;
    if (shape[size_t(a)] == 1) continue;
    if (!axes.empty() && axes.back().second == shape[size_t(a)] * in_stride[size_t(a)]) {
      axes.back() = {axes.back().first * shape[size_t(a)], in_stride[size_t(a)]};
    } else {
      axes.push_back({shape[size_t(a)], in_stride[size_t(a)]});
    }
  }
  const int64_t n = shape_numel(shape);
  if (n == 0) return;
  if (axes.empty()) axes.push_back({1, 1});
  if (axes.size() > 6) fail(op, "more than 6 axes remain after merging adjacent ones");
  if (axes.size() == 1) {  // nothing moves
    rec.copy(in, out, VkDeviceSize(n) * 4);
    return;
  }
  permute_split(rec, op, in, out, axes);
}

// Patchify is the permute [BF, C, Hp, p, Wp, p] -> [BF, Hp, Wp, C, p, p] (and back); a dedicated shader moves
// whole patches (one vec4 per patch for p = 2) instead of decomposing six indices per element.
void record_patches_range(vk::Recorder& rec, const char* op, bool inverse, const vk::BufferView& in,
                    const vk::BufferView& out, int64_t BF, int64_t C, int64_t Hp, int64_t Wp, int64_t p) {
  const int64_t patches = BF * C * Hp * Wp;
  if (patches == 0) return;
  struct {
    uint32_t rows, C, Hp, Wp, p;
  } push{uint32_t(BF * Hp), uint32_t(C), uint32_t(Hp), uint32_t(Wp), uint32_t(p)};
  std::string shader = inverse ? "nn/patchify_inverse" : "nn/patchify";
  if (p == 2) shader += "_p2";
  const vk::Pipeline& pipe = rec.context().pipelines().get(shader);
  // 32 invocations per group over wp; about kMaxGroups groups in all.
  const vk::DeviceCaps& caps = rec.context().caps();
  const uint32_t gx = div_up(Wp, 32);
  if (gx > caps.max_workgroup_count[0])
    fail(op, "a row of " + std::to_string(Wp) + " patches needs too many workgroups");
  const int64_t gy = std::clamp<int64_t>(BF * Hp, 1, std::max<int64_t>(1, kMaxGroups / gx));
  const uint32_t gy_max = caps.max_workgroup_count[1];
  rec.dispatch(pipe, {in, out}, &push, sizeof push, gx, uint32_t(std::min<int64_t>(gy, gy_max)), 1, op);
}

// Frames (BF) in chunks whose input and output (the same size) fit one binding each.
void record_patches(vk::Recorder& rec, const char* op, bool inverse, const vk::BufferView& in,
                    const vk::BufferView& out, int64_t BF, int64_t C, int64_t Hp, int64_t Wp, int64_t p) {
  const uint64_t frame = uint64_t(C * Hp * Wp * p * p) * 4;
  const int64_t per = rows_per_chunk(rec.context().caps(), op, {RowOperand{frame, 0}}, BF);
  if (per >= BF) return record_patches_range(rec, op, inverse, in, out, BF, C, Hp, Wp, p);
  rec.context().note_split(op);
  for_each_chunk(BF, per, [&](int64_t f0, int64_t nf) {
    record_patches_range(rec, op, inverse, in.sub(f0 * frame, nf * frame), out.sub(f0 * frame, nf * frame), nf, C, Hp,
                         Wp, p);
  });
}


void record_rows(vk::Recorder& rec, const char* op, const Tensor& src, const Tensor* src_idx, const Tensor* dst_idx,
                 const Tensor& dst) {
  check_words(op, src);
  check_words(op, dst);
  if (src.dtype() != dst.dtype()) fail(op, src.describe() + " and " + dst.describe() + " differ in dtype");
  if (src.rank() == 0 || dst.rank() == 0) fail(op, "rows need a tensor of rank ≥ 1");
  const int64_t src_rows = src.shape()[0], dst_rows = dst.shape()[0];
  const int64_t len = src_rows ? src.numel() / src_rows : 0, dst_len = dst_rows ? dst.numel() / dst_rows : 0;
  if (src_rows && dst_rows && len != dst_len)
    fail(op, "rows of " + src.describe() + " and " + dst.describe() + " differ in length");
  int64_t m = -1;
  for (const Tensor* idx : {src_idx, dst_idx}) {
    if (!idx) continue;
    expect_dtype(op, "indices", *idx, DType::i32);
    if (m >= 0 && idx->numel() != m) fail(op, "index lists differ in length");
    m = idx->numel();
  }
  if (!src_idx && m != src_rows) fail(op, "source " + src.describe() + " must have one row per index");
  if (!dst_idx && m != dst_rows) fail(op, "destination " + dst.describe() + " must have one row per index");
  if (m == 0 || len == 0 || dst_rows == 0) return;
  const bool vec4 = len % 4 == 0;
  const int64_t q = vec4 ? 4 : 1;
  const vk::DeviceCaps& caps = rec.context().caps();
  const uint64_t row_bytes = uint64_t(len) * 4;
  // Index rows i in chunks bounding the index lists and the side walked by i (src without src_idx, dst
  // without dst_idx); an indexed side is a table, bound in row ranges (each dispatch moves the rows whose
  // indices fall in its range).
  const int64_t per_i = rows_per_chunk(caps, op, {RowOperand{src_idx ? 0 : row_bytes, 0},
                                                  RowOperand{dst_idx ? 0 : row_bytes, 0}, RowOperand{4, 0}}, m);
  const int64_t per_src = src_idx ? rows_per_chunk(caps, op, {RowOperand{row_bytes, 0}}, src_rows) : m;
  const int64_t per_dst = dst_idx ? rows_per_chunk(caps, op, {RowOperand{row_bytes, 0}}, dst_rows) : m;
  const vk::Pipeline& p = rec.context().pipelines().get(vec4 ? "nn/gather_rows_vec4" : "nn/gather_rows");
  auto rows_of = [&](const Tensor& t, int64_t first, int64_t count) {
    return t.buffer().sub(VkDeviceSize(first) * row_bytes, VkDeviceSize(count) * row_bytes);
  };
  auto ids_of = [&](const Tensor* idx, int64_t first, int64_t count) {
    return count == m ? idx->buffer() : idx->buffer().sub(VkDeviceSize(first) * 4, VkDeviceSize(count) * 4);
  };
  if (per_i < m || per_src < src_rows || per_dst < dst_rows) rec.context().note_split(op);
  for_each_chunk(m, per_i, [&](int64_t i0, int64_t mi) {
    // An empty source table still runs once: every index is outside it and reads zeros.
    for_each_chunk(src_idx ? std::max<int64_t>(src_rows, 1) : 1, src_idx ? per_src : 1, [&](int64_t s0, int64_t ns) {
      ns = std::min(ns, src_rows);
      for_each_chunk(dst_idx ? dst_rows : 1, dst_idx ? per_dst : 1, [&](int64_t d0, int64_t nd) {
        const Grid2 g = grid_rows(caps, mi, len / q);
        struct {
          uint32_t m, len, src_rows, dst_rows, use_src_idx, use_dst_idx, lane_rows;
          uint32_t src_first, src_total, dst_first, dst_total;
        } push{uint32_t(mi), uint32_t(len / q), uint32_t(src_idx ? ns : mi), uint32_t(dst_idx ? nd : mi),
               src_idx != nullptr, dst_idx != nullptr, g.lane_rows, uint32_t(src_idx ? s0 : 0),
               uint32_t(src_rows), uint32_t(dst_idx ? d0 : 0), uint32_t(dst_rows)};
        const vk::BufferView sv = src_idx ? (ns == src_rows ? src.buffer() : rows_of(src, s0, ns))
                                          : (mi == m ? src.buffer() : rows_of(src, i0, mi));
        const vk::BufferView dv = dst_idx ? (nd == dst_rows ? dst.buffer() : rows_of(dst, d0, nd))
                                          : (mi == m ? dst.buffer() : rows_of(dst, i0, mi));
        // An absent index list binds any readable buffer; the shader does not read it.
        const vk::BufferView si = src_idx ? ids_of(src_idx, i0, mi) : dst_idx ? ids_of(dst_idx, i0, mi) : sv;
        const vk::BufferView di = dst_idx ? ids_of(dst_idx, i0, mi) : si;
        rec.dispatch(p, {sv, si, di, dv}, &push, sizeof push, g.x, g.y, 1, op);
      });
    });
  });
}

}  // namespace

void concat(vk::Recorder& rec, const std::vector<Tensor>& inputs, const Tensor& out, int axis) {
  bands(rec, "concat", out, inputs, axis, true);
}

void split(vk::Recorder& rec, const Tensor& in, const std::vector<Tensor>& outputs, int axis) {
  bands(rec, "split", in, outputs, axis, false);
}

void permute(vk::Recorder& rec, const Tensor& in, const Tensor& out, const std::vector<int>& perm) {
  check_words("permute", in);
  expect_dtype("permute", "out", out, in.dtype());
  if (perm.size() != in.rank()) fail("permute", "permutation length differs from rank of " + in.describe());
  Shape want(in.rank());
  for (size_t d = 0; d < in.rank(); ++d) {
    if (perm[d] < 0 || size_t(perm[d]) >= in.rank()) fail("permute", "invalid permutation");
    want[d] = in.shape()[size_t(perm[d])];
  }
  expect_shape("permute", "out", out, want);
  permute_words(rec, "permute", in.buffer(), out.buffer(), in.shape(), perm);
}

void patchify(vk::Recorder& rec, const Tensor& in, const Tensor& out, int p) {
  check_words("patchify", in);
  expect_dtype("patchify", "out", out, in.dtype());
  if (in.rank() != 5 || p < 1 || in.dim(3) % p || in.dim(4) % p)
    fail("patchify", in.describe() + " is not [B, F, C, H, W] with H and W multiples of " + std::to_string(p));
  const int64_t B = in.dim(0), F = in.dim(1), C = in.dim(2), Hp = in.dim(3) / p, Wp = in.dim(4) / p;
  expect_shape("patchify", "out", out, {B, F * Hp * Wp, C * p * p});
  record_patches(rec, "patchify", false, in.buffer(), out.buffer(), B * F, C, Hp, Wp, p);
}

void unpatchify(vk::Recorder& rec, const Tensor& in, const Tensor& out, int p) {
  check_words("unpatchify", in);
  expect_dtype("unpatchify", "out", out, in.dtype());
  if (out.rank() != 5 || p < 1 || out.dim(3) % p || out.dim(4) % p)
    fail("unpatchify", out.describe() + " is not [B, F, C, H, W] with H and W multiples of " + std::to_string(p));
  const int64_t B = out.dim(0), F = out.dim(1), C = out.dim(2), Hp = out.dim(3) / p, Wp = out.dim(4) / p;
  expect_shape("unpatchify", "in", in, {B, F * Hp * Wp, C * p * p});
  record_patches(rec, "unpatchify", true, in.buffer(), out.buffer(), B * F, C, Hp, Wp, p);
}

void gather_rows(vk::Recorder& rec, const Tensor& src, const Tensor& idx, const Tensor& out) {
  record_rows(rec, "gather_rows", src, &idx, nullptr, out);
}

void scatter_rows(vk::Recorder& rec, const Tensor& src, const Tensor& idx, const Tensor& dst) {
  record_rows(rec, "scatter_rows", src, nullptr, &idx, dst);
}

void gather_scatter_rows(vk::Recorder& rec, const Tensor& src, const Tensor& src_idx, const Tensor& dst_idx,
                         const Tensor& dst) {
  record_rows(rec, "gather_scatter_rows", src, &src_idx, &dst_idx, dst);
}

}  // namespace dvs::ops
