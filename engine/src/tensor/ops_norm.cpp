#include "tensor/ops_norm.hpp"

#include <algorithm>
#include <numeric>
#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_reduce.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops {
namespace {

constexpr uint32_t kRowLocal = 256;  // most invocations per row for layernorm / rmsnorm
constexpr int64_t kRowCache = 4;    // most vec4 per invocation kept in registers (more would spill)

// One invocation per row or a workgroup per row: a device choice (DeviceTuning::norm_row_per_invocation;
// tests and benchmarks force either with ScopedTuningOverride("norm_row_per_invocation=on|off")).
bool row_per_invocation(vk::Recorder& rec) { return device_tuning(rec.context().caps()).norm_row_per_invocation; }

// Invocations per row: a power of two from 8 to kRowLocal covering the row's n (vec4s or floats) in
// kRowCache per invocation.
uint32_t row_local(int64_t n) {
  uint32_t local = 8;
  while (local < kRowLocal && local * kRowCache < n) local *= 2;
  return local;
}

// Storage code of a weight dtype in the shaders (WDTYPE), after checking size and dtype.
uint32_t weight_code(const char* op, const char* arg, const Tensor& w, int64_t n) {
  if (w.numel() != n)
    throw Error(std::string("internal: ") + op + ": " + arg + " is " + w.describe() + ", expected " +
                std::to_string(n) + " elements");
  switch (w.dtype()) {
    case DType::f32: return 0;
    case DType::bf16: return 1;
    case DType::f16: return 2;
    default: throw Error(std::string("internal: ") + op + ": " + arg + " has dtype " + dtype_name(w.dtype()) +
                         ", expected f32, bf16 or f16");
  }
}

// The shaders declare every buffer as an array of 16-byte vectors (vec4 / uvec4) and index components for
// odd sizes, so each view is widened to whole 16-byte units. Suballocations and arena views are aligned to
// at least 64 bytes, so the padding bytes belong to the same allocation and are never written.
vk::BufferView vec4_view(const vk::BufferView& view) {
  vk::BufferView v = view;
  v.size = (v.size + 15) / 16 * 16;
  return v;
}
vk::BufferView vec4_view(const Tensor& t) { return vec4_view(t.buffer()); }

// Affine pair: both defined (same dtype) or neither. Returns the WDTYPE code, or -1 without affine.
int affine_code(const char* op, const Tensor& w, const Tensor& b, int64_t n) {
  if (!w.defined() && !b.defined()) return -1;
  if (!w.defined() || !b.defined()) throw Error(std::string("internal: ") + op + ": weight and bias must both be given");
  uint32_t cw = weight_code(op, "weight", w, n), cb = weight_code(op, "bias", b, n);
  if (cw != cb) throw Error(std::string("internal: ") + op + ": weight and bias dtypes differ");
  return int(cw);
}

void check_rows(const char* op, const Tensor& x, const Tensor& y, bool y_may_be_f16 = false) {
  expect_dtype(op, "x", x, DType::f32);
  if (!(y_may_be_f16 && y.dtype() == DType::f16)) expect_dtype(op, "y", y, DType::f32);
  expect_shape(op, "y", y, x.shape());
  if (x.rank() < 1 || x.numel() == 0) throw Error(std::string("internal: ") + op + ": empty input " + x.describe());
  if (x.numel() > int64_t(UINT32_MAX)) throw Error(std::string("internal: ") + op + ": " + x.describe() + " too large");
}

// Elements reserved for one statistics vector in groupnorm's scratch: sub-views start 256-byte aligned
// (the largest minStorageBufferOffsetAlignment Vulkan allows).
int64_t stats_span(int64_t n) { return (n + 63) / 64 * 64; }

// Rows per dispatch of a row-wise op whose x and y rows are `row_bytes` each: all of them when they fit one
// binding, else as many as fit with the alignment slack of a chunk bound from an aligned-down offset; never
// more than `max_rows` (the grid, or what else the op binds per row range). A row wider than a binding would
// need split statistics: at real sizes rows are at most 16 KiB (T5, 4096 wide) against at least 128 MiB.
int64_t row_chunk(const vk::DeviceCaps& caps, const char* op, uint64_t row_bytes, int64_t rows, int64_t max_rows) {
  const uint64_t cap = binding_capacity(caps, 0);
  if (uint64_t(rows) * row_bytes <= cap && rows <= max_rows) return rows;
  const int64_t chunk = std::min<int64_t>(int64_t((cap - binding_alignment(caps)) / row_bytes), max_rows);
  if (chunk < 1)
    throw Error(std::string("internal: ") + op + ": a row of " + std::to_string(row_bytes) +
                " bytes does not fit one binding of " + std::to_string(cap) +
                " bytes with its alignment slack (or the grid / modulation table allow no row)");
  return chunk;
}

// Rows [first, first + count) of a row-major [rows, row_elems] f32 tensor as one binding's view, from an
// aligned-down offset: row `first` starts `off` elements into the view.
struct RowView {
  vk::BufferView view;
  uint32_t off = 0;
};
RowView row_view(const vk::DeviceCaps& caps, const Tensor& t, int64_t row_elems, int64_t first, int64_t count) {
  const uint64_t es = dtype_size(t.dtype());
  const uint64_t start = uint64_t(first * row_elems) * es, delta = start % binding_alignment(caps);
  return {vec4_view(t.buffer().sub(start - delta, uint64_t(count * row_elems) * es + delta)), uint32_t(delta / es)};
}

}  // namespace

void layernorm(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& weight, const Tensor& bias,
               float eps, const Modulation* mod) {
  const char* op = "layernorm";
  check_rows(op, x, y, true);
  const int64_t D = x.dim(-1), rows = x.numel() / D;
  int code = affine_code(op, weight, bias, D);
  struct {
    uint32_t rows, D;
    float eps;
    uint32_t L, split, table_stride;
    uint32_t shift0, scale0, shift1, scale1;  // column offsets into a table row
    uint32_t row0, table_row0, table_off;     // chunk: first row, first table row bound, its element offset
    uint32_t x_off, y_off;                    // chunk: element offset of its first row in the x / y view
  } p{uint32_t(rows), uint32_t(D), eps, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
  int64_t W = 0;
  if (mod) {
    expect_dtype(op, "modulation table", mod->table, DType::f32);
    if (mod->table.rank() != 2 || mod->seq_len < 1 || rows % mod->seq_len != 0 ||
        mod->table.dim(0) != rows / mod->seq_len || mod->split < 0 || mod->split > mod->seq_len)
      throw Error("internal: layernorm: modulation table " + mod->table.describe() + " / seq_len " +
                  std::to_string(mod->seq_len) + " / split " + std::to_string(mod->split) + " do not fit " +
                  x.describe());
    W = mod->table.dim(1);
    for (int s = 0; s < 2; ++s)
      if (mod->shift_col[s] < 0 || mod->scale_col[s] < 0 || mod->shift_col[s] + D > W || mod->scale_col[s] + D > W)
        throw Error("internal: layernorm: modulation columns outside the table " + mod->table.describe());
    p.L = uint32_t(mod->seq_len);
    p.split = uint32_t(mod->split);
    p.table_stride = uint32_t(W);
    p.shift0 = uint32_t(mod->shift_col[0]);
    p.scale0 = uint32_t(mod->scale_col[0]);
    p.shift1 = uint32_t(mod->shift_col[1]);
    p.scale1 = uint32_t(mod->scale_col[1]);
  }
  bool vec4 = D % 4 == 0;
  if (mod) vec4 = vec4 && p.table_stride % 4 == 0 && (p.shift0 | p.scale0 | p.shift1 | p.scale1) % 4 == 0;
  const bool y16 = y.dtype() == DType::f16;
  if (y16 && (!vec4 || y.buffer().offset % 8))
    throw Error("internal: layernorm: an f16 y needs D, the modulation columns and y's offset on 4-element "
                "boundaries, got " + y.describe());
  const int64_t n4 = vec4 ? D / 4 : D;
  const bool per_invocation = row_per_invocation(rec);
  const uint32_t local = per_invocation ? 64u : row_local(n4);
  const uint32_t cache =
      vec4 && !per_invocation ? uint32_t(std::min<int64_t>(kRowCache, (n4 + local - 1) / local)) : 1u;
  uint32_t spec[] = {local,          code < 0 ? 0u : uint32_t(code), code >= 0 ? 1u : 0u, mod ? 1u : 0u,
                     vec4 ? 1u : 0u, cache,                          per_invocation ? 1u : 0u, y16 ? 1u : 0u};
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/layernorm", spec);
  const vk::DeviceCaps& caps = rec.context().caps();
  const uint32_t rows_per_group = per_invocation ? 64 : 1;
  int64_t max_rows = int64_t(max_groups_1d(caps)) * rows_per_group;
  int64_t col_lo = 0, col_hi = 0;  // table columns a row may read
  if (mod) {
    // A chunk of r rows touches at most 1 + ceil((r-1)/L) table rows; bound r so that their slice fits.
    col_lo = std::min({p.shift0, p.scale0, p.shift1, p.scale1});
    col_hi = std::max({p.shift0, p.scale0, p.shift1, p.scale1}) + D;
    const int64_t room = int64_t((binding_capacity(caps, 0) - binding_alignment(caps)) / 4) - (col_hi - col_lo);
    if (room < 0) throw Error("internal: layernorm: one modulation table row's slice exceeds a binding");
    max_rows = std::min(max_rows, (room / W) * mod->seq_len + 1);
  }
  const int64_t chunk = row_chunk(caps, op, uint64_t(D) * 4, rows, max_rows);
  // Unused bindings get a harmless read-only view (x's chunk).
  vk::BufferView wv = code >= 0 ? vec4_view(weight) : vk::BufferView{}, bv = code >= 0 ? vec4_view(bias) : wv;
  if (chunk < rows) rec.context().note_split(op);  // once per call, not per chunk
  for_each_chunk(rows, chunk, [&](int64_t r0, int64_t rc) {
    const RowView xr = row_view(caps, x, D, r0, rc);
    vk::BufferView xv = xr.view, mv = xv;
    p.rows = uint32_t(rc);
    p.row0 = uint32_t(r0);
    const RowView yr = row_view(caps, y, D, r0, rc);
    p.x_off = xr.off;
    p.y_off = yr.off;
    if (mod) {
      // The table rows of the batches this chunk touches (a chunk may start inside a batch), bound from an
      // aligned-down offset: the shader adds table_off elements.
      const int64_t t0 = r0 / mod->seq_len, t1 = (r0 + rc - 1) / mod->seq_len;
      const uint64_t first = uint64_t(t0 * W + col_lo) * 4, delta = first % binding_alignment(caps);
      mv = vec4_view(mod->table.buffer().sub(first - delta, uint64_t((t1 - t0) * W + col_hi - col_lo) * 4 + delta));
      p.table_row0 = uint32_t(t0);
      p.table_off = uint32_t(delta / 4) - uint32_t(col_lo);  // wraps; the shader adds the columns back
    }
    Grid g = grid_1d(caps, rc, rows_per_group);
    rec.dispatch(pipe, {xv, yr.view, code >= 0 ? wv : xv, code >= 0 ? bv : xv, mv}, &p,
                 sizeof p, g.x, g.y, 1, "layernorm");
  });
}

void head_layernorm(vk::Recorder& rec, const Tensor& x, const Tensor& y, int64_t heads, int64_t head_dim,
                    int64_t col_offset, const Tensor& weight, const Tensor& bias, float eps) {
  const char* op = "head_layernorm";
  check_rows(op, x, y);
  if (x.rank() != 2) throw Error("internal: head_layernorm: x must be [rows, row_stride], got " + x.describe());
  const int64_t rows = x.dim(0), stride = x.dim(1);
  if (heads < 1 || head_dim < 1 || col_offset < 0 || col_offset + heads * head_dim > stride)
    throw Error("internal: head_layernorm: " + std::to_string(heads) + " heads of " + std::to_string(head_dim) +
                " from column " + std::to_string(col_offset) + " do not fit " + x.describe());
  int code = affine_code(op, weight, bias, head_dim);
  struct {
    uint32_t rows, H, Dh, row_stride, col_offset;
    float eps;
  } p{uint32_t(rows), uint32_t(heads), uint32_t(head_dim), uint32_t(stride), uint32_t(col_offset), eps};
  const bool vec4 = head_dim % 4 == 0 && head_dim <= 256 && stride % 4 == 0 && col_offset % 4 == 0;
  uint32_t spec[] = {code < 0 ? 0u : uint32_t(code), code >= 0 ? 1u : 0u, vec4 ? 1u : 0u,
                     vec4 ? uint32_t(head_dim / 4) : 1u};
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/headnorm", spec);
  // Row chunks of the whole fused rows; one invocation per (row, head).
  const vk::DeviceCaps& caps = rec.context().caps();
  const int64_t chunk = row_chunk(caps, op, uint64_t(stride) * 4, rows, int64_t(max_groups_1d(caps)) * 64 / heads);
  if (chunk < rows) rec.context().note_split(op);  // once per call, not per chunk
  for_each_chunk(rows, chunk, [&](int64_t r0, int64_t rc) {
    const RowView xr = row_view(caps, x, stride, r0, rc);
    vk::BufferView xv = xr.view, wv = code >= 0 ? vec4_view(weight) : xv, bv = code >= 0 ? vec4_view(bias) : xv;
    p.rows = uint32_t(rc);
    p.col_offset = uint32_t(col_offset) + xr.off;  // the view's offset folds into the column offset
    Grid g = grid_1d(caps, rc * heads, 64);
    rec.dispatch(pipe, {xv, row_view(caps, y, stride, r0, rc).view, wv, bv}, &p, sizeof p, g.x, g.y, 1,
                 "head_layernorm");
  });
}

void attention_heads(vk::Recorder& rec, const Tensor& x, const Tensor& y, int64_t heads,
                     const AttentionHeadsOptions& o) {
  const char* op = "attention_heads";
  expect_dtype(op, "x", x, DType::f32);
  if (y.dtype() != DType::f16) expect_dtype(op, "y", y, DType::f32);
  if (x.rank() != 3 || heads < 1 || x.dim(2) % heads)
    throw Error("internal: attention_heads: x must be [B, L, H·D] with H = " + std::to_string(heads) + ", got " +
                x.describe());
  const int64_t B = x.dim(0), L = x.dim(1), D = x.dim(2) / heads, rows = B * L;
  expect_shape(op, "y", y, {B, heads, L, D});
  if (D % 4 || D > 256)
    throw Error("internal: attention_heads: head_dim " + std::to_string(D) + " is not a multiple of 4 up to 256");
  const uint64_t ye = dtype_size(y.dtype());
  if (x.buffer().offset % 16 || y.buffer().offset % (4 * ye))
    throw Error("internal: attention_heads: x must start at a multiple of 16 bytes and y at one of " +
                std::to_string(4 * ye) + " (" + x.describe() + ", " + y.describe() + ")");
  const int code = o.norm ? affine_code(op, o.norm_weight, o.norm_bias, D) : -1;
  int64_t n_rot = 0;
  if (o.rope) {
    expect_dtype(op, "cos", o.cos, DType::f32);
    expect_dtype(op, "sin", o.sin, DType::f32);
    if (o.cos.rank() != 2 || o.cos.dim(1) != D) throw Error("internal: attention_heads: cos is " + o.cos.describe());
    expect_shape(op, "sin", o.sin, o.cos.shape());
    n_rot = o.cos.dim(0);
    if (o.rope_first < 0 || o.rope_first + n_rot > L)
      throw Error("internal: attention_heads: tokens [" + std::to_string(o.rope_first) + ", " +
                  std::to_string(o.rope_first + n_rot) + ") to rotate do not fit " + std::to_string(L) + " tokens");
  }
  if (rows == 0) return;
  const vk::DeviceCaps& caps = rec.context().caps();
  const uint64_t cap = binding_capacity(caps, 0), align = binding_alignment(caps);
  for (const Tensor* t : {&y, &o.cos, &o.sin})
    if (t->defined() && t->bytes() + align > cap)
      throw Error("attention_heads: " + t->describe() + " does not fit one binding of " + std::to_string(cap) +
                      " bytes (maxStorageBufferRange or DVS_LIMITS); the attention that reads it would not either",
                  ErrorKind::device);
  if (uint64_t(y.numel()) / 4 > UINT32_MAX) throw Error("internal: attention_heads: " + y.describe() + " too large");
  uint32_t y_base = 0;
  const vk::BufferView yv = aligned_view(y.buffer(), 0, y.bytes(), align, uint32_t(4 * ye), y_base);
  const bool rope = n_rot > 0;  // asked for, with rows to rotate
  const vk::BufferView cv = rope ? vec4_view(o.cos) : yv, sv = rope ? vec4_view(o.sin) : yv;
  const vk::BufferView wv = code >= 0 ? vec4_view(o.norm_weight) : yv, bv = code >= 0 ? vec4_view(o.norm_bias) : yv;
  const uint32_t spec[] = {code < 0 ? 0u : uint32_t(code), o.norm ? 1u : 0u, code >= 0 ? 1u : 0u, rope ? 1u : 0u,
                           ye == 2 ? 1u : 0u, uint32_t(D / 4)};
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/attention_heads", spec);
  struct {
    uint32_t rows, row0, L, H, rope_first, n_rot, x_off, y_off;
    float eps;
  } p{0, 0, uint32_t(L), uint32_t(heads), uint32_t(o.rope_first), uint32_t(n_rot), 0, 0u - y_base, o.eps};
  // Row chunks of x; one invocation per (row, head).
  const int64_t chunk = row_chunk(caps, op, uint64_t(x.dim(2)) * 4, rows, int64_t(max_groups_1d(caps)) * 64 / heads);
  if (chunk < rows) rec.context().note_split(op);  // once per call, not per chunk
  for_each_chunk(rows, chunk, [&](int64_t r0, int64_t rc) {
    const RowView xr = row_view(caps, x, x.dim(2), r0, rc);
    p.rows = uint32_t(rc);
    p.row0 = uint32_t(r0);
    p.x_off = xr.off / 4;
    const Grid g = grid_1d(caps, rc * heads, 64);
    rec.dispatch(pipe, {xr.view, yv, wv, bv, cv, sv}, &p, sizeof p, g.x, g.y, 1, op);
  });
}

void rmsnorm(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& weight, float eps) {
  const char* op = "rmsnorm";
  check_rows(op, x, y);
  const int64_t D = x.dim(-1), rows = x.numel() / D;
  uint32_t code = weight_code(op, "weight", weight, D);
  struct {
    uint32_t rows, D;
    float eps;
    uint32_t x_off;  // chunk: element offset of its first row in the x/y views
  } p{uint32_t(rows), uint32_t(D), eps, 0};
  const bool vec4 = D % 4 == 0;
  const int64_t n4 = vec4 ? D / 4 : D;
  const bool per_invocation = row_per_invocation(rec);
  const uint32_t local = per_invocation ? 64u : row_local(n4);
  const uint32_t cache =
      vec4 && !per_invocation ? uint32_t(std::min<int64_t>(kRowCache, (n4 + local - 1) / local)) : 1u;
  uint32_t spec[] = {local, code, vec4 ? 1u : 0u, cache, per_invocation ? 1u : 0u};
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/rmsnorm", spec);
  const vk::DeviceCaps& caps = rec.context().caps();
  const uint32_t rows_per_group = per_invocation ? 64 : 1;
  const int64_t chunk = row_chunk(caps, op, uint64_t(D) * 4, rows, int64_t(max_groups_1d(caps)) * rows_per_group);
  if (chunk < rows) rec.context().note_split(op);  // once per call, not per chunk
  for_each_chunk(rows, chunk, [&](int64_t r0, int64_t rc) {
    const RowView xr = row_view(caps, x, D, r0, rc);
    p.rows = uint32_t(rc);
    p.x_off = xr.off;
    Grid g = grid_1d(caps, rc, rows_per_group);
    rec.dispatch(pipe, {xr.view, row_view(caps, y, D, r0, rc).view, vec4_view(weight)}, &p, sizeof p, g.x, g.y, 1,
                 "rmsnorm");
  });
}

int64_t groupnorm_scratch_elems(const Shape& s, int64_t groups) {
  if (s.size() < 2 || groups < 1) throw Error("internal: groupnorm: bad shape or group count");
  const int64_t B = s[0], group_len = shape_numel(s) / B / groups;
  return 2 * stats_span(B * groups) + reduce_scratch_elems(B * groups, group_len);
}

void groupnorm(vk::Recorder& rec, const Tensor& x, const Tensor& y, int64_t groups, const Tensor& gamma,
               const Tensor& beta, float eps, bool silu, const Tensor& scratch) {
  const char* op = "groupnorm";
  check_rows(op, x, y);
  if (x.rank() < 2) throw Error("internal: groupnorm: x must be [B, C, ...], got " + x.describe());
  const int64_t B = x.dim(0), C = x.dim(1), S = x.numel() / (B * C);
  if (groups < 1 || C % groups != 0)
    throw Error("internal: groupnorm: " + std::to_string(C) + " channels do not split into " + std::to_string(groups) +
                " groups");
  int code = affine_code(op, gamma, beta, C);
  expect_dtype(op, "scratch", scratch, DType::f32);
  const int64_t need = groupnorm_scratch_elems(x.shape(), groups);
  if (scratch.numel() < need)
    throw Error("internal: groupnorm: scratch " + scratch.describe() + " smaller than " + std::to_string(need));

  // Scratch layout: [mean (B*G) | var (B*G) | block partials], each part 256-byte aligned.
  const int64_t n_groups = B * groups, group_len = (C / groups) * S, span = stats_span(n_groups);
  Tensor mean = Tensor::on(scratch.buffer().sub(0, n_groups * 4), {n_groups}, DType::f32);
  Tensor var = Tensor::on(scratch.buffer().sub(span * 4, n_groups * 4), {n_groups}, DType::f32);
  const int64_t part_elems = need - 2 * span;
  Tensor parts = Tensor::on(scratch.buffer().sub(2 * span * 4, part_elems * 4), {part_elems}, DType::f32);
  const vk::DeviceCaps& caps = rec.context().caps();
  const uint64_t cap = binding_capacity(caps, 0), align = binding_alignment(caps);
  const uint64_t max_gy = caps.max_workgroup_count[1], max_gx = caps.max_workgroup_count[0];

  // Statistics: groups are contiguous runs of group_len elements; chunks of whole groups (aligned starts),
  // each reduced by the same two-level partials + Chan merge into its slots of mean/var. A group larger than
  // one binding is left to reduce_segments' own splitting.
  const uint64_t group_bytes = uint64_t(group_len) * 4, granule = align / std::gcd(align, group_bytes);
  const bool stats_fit = uint64_t(n_groups) * group_bytes <= cap && uint64_t(n_groups) <= std::min(max_gx, max_gy);
  int64_t gchunk = n_groups;
  if (!stats_fit && granule * group_bytes <= cap && granule <= std::min(max_gx, max_gy)) {
    gchunk = rows_per_chunk(caps, op, {RowOperand{group_bytes, 0}}, n_groups);
    gchunk = std::min<int64_t>(gchunk, int64_t(std::min(max_gx, max_gy) / granule * granule));
    while (gchunk > int64_t(granule) && reduce_scratch_elems(gchunk, group_len) > part_elems)
      gchunk -= int64_t(granule);
  }
  for_each_chunk(n_groups, gchunk, [&](int64_t g0, int64_t gc) {
    const Tensor xs = gc == n_groups ? x
                                     : Tensor::on(x.buffer().sub(VkDeviceSize(g0 * group_len) * 4,
                                                                 VkDeviceSize(gc * group_len) * 4),
                                                  {gc * group_len}, DType::f32);
    reduce_segments(rec, xs, {gc, group_len, group_len, group_len, 0}, ReduceMode::mean_var, mean, var, parts, g0);
  });

  // Apply: chunks of whole (b, c) planes, or of one plane's elements when a plane exceeds a binding or the
  // grid; each chunk bound from an aligned-down offset that the shader adds (x_off).
  struct {
    uint32_t C, S, channels_per_group;
    float eps;
    uint32_t plane0, x_off, len;  // chunk: first plane, element offset in the views, elements per plane
  } p{uint32_t(C), uint32_t(S), uint32_t(C / groups), eps, 0, 0, uint32_t(S)};
  const bool vec4 = S % 4 == 0;
  uint32_t spec[] = {code < 0 ? 0u : uint32_t(code), code >= 0 ? 1u : 0u, silu ? 1u : 0u, vec4 ? 1u : 0u};
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/groupnorm_apply", spec);
  // Without affine, gamma/beta bind the (small) mean vector: never read.
  vk::BufferView wv = code >= 0 ? vec4_view(gamma) : mean.buffer(), bv = code >= 0 ? vec4_view(beta) : mean.buffer();
  const int64_t per_group = 64 * 16 * (vec4 ? 4 : 1);  // elements per workgroup: LOCAL * ITEMS (vec4s with VEC4)
  const int64_t planes = B * C;
  const uint64_t plane_bytes = uint64_t(S) * 4;
  int64_t pc = planes, len = S;  // planes per chunk, elements per plane chunk
  const bool plane_fits = plane_bytes + align <= cap && uint64_t(div_up(S, per_group)) <= max_gx;
  if (!(uint64_t(planes) * plane_bytes <= cap && uint64_t(planes) <= max_gy && plane_fits)) {
    if (plane_fits) {
      pc = std::min<int64_t>(int64_t((cap - align) / plane_bytes), int64_t(max_gy));
    } else {
      pc = 1;
      len = std::min<int64_t>(int64_t((cap - align) / 4), int64_t(max_gx) * per_group) / 4 * 4;
      if (len < 4) throw Error("internal: groupnorm: a binding holds fewer than 4 elements");
    }
  }
  // One note per call: split statistics (rows of groups over several bindings) or a split apply.
  if (!stats_fit || pc < planes || len < S) rec.context().note_split(op);
  for_each_chunk(planes, pc, [&](int64_t p0, int64_t np) {
    for_each_chunk(S, len, [&](int64_t s0, int64_t n) {
      const uint64_t first = uint64_t(p0 * S + s0) * 4, delta = first % align;
      const uint64_t bytes = uint64_t((np - 1) * S + n) * 4 + delta;
      p.plane0 = uint32_t(p0);
      p.x_off = uint32_t(delta / 4);
      p.len = uint32_t(n);
      rec.dispatch(pipe,
                   {vec4_view(x.buffer().sub(first - delta, bytes)), vec4_view(y.buffer().sub(first - delta, bytes)),
                    wv, bv, mean.buffer(), var.buffer()},
                   &p, sizeof p, div_up(n, per_group), uint32_t(np), 1, "groupnorm_apply");
    });
  });
}

}  // namespace dvs::ops
