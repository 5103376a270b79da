#include "tensor/ops_norm.hpp"

#include <algorithm>
#include <string>

#include "tensor/ops_reduce.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops {
namespace {

constexpr uint32_t kRowLocal = 256;  // most invocations per row for layernorm / rmsnorm
constexpr int64_t kRowCache = 4;    // most vec4 per invocation kept in registers (more would spill)

RowMapping g_row_mapping = RowMapping::automatic;

bool row_per_invocation(vk::Recorder& rec) {
  if (g_row_mapping != RowMapping::automatic) return g_row_mapping == RowMapping::invocation_per_row;
  return rec.context().caps().type == VK_PHYSICAL_DEVICE_TYPE_CPU;
}

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

void check_rows(const char* op, const Tensor& x, const Tensor& y) {
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect_shape(op, "y", y, x.shape());
  if (x.rank() < 1 || x.numel() == 0) throw Error(std::string("internal: ") + op + ": empty input " + x.describe());
  if (x.numel() > int64_t(UINT32_MAX)) throw Error(std::string("internal: ") + op + ": " + x.describe() + " too large");
}

// Elements reserved for one statistics vector in groupnorm's scratch: sub-views start 256-byte aligned
// (the largest minStorageBufferOffsetAlignment Vulkan allows).
int64_t stats_span(int64_t n) { return (n + 63) / 64 * 64; }

}  // namespace

void set_row_mapping(RowMapping mapping) { g_row_mapping = mapping; }

void layernorm(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& weight, const Tensor& bias,
               float eps, const Modulation* mod) {
  const char* op = "layernorm";
  check_rows(op, x, y);
  const int64_t D = x.dim(-1), rows = x.numel() / D;
  int code = affine_code(op, weight, bias, D);
  struct {
    uint32_t rows, D;
    float eps;
    uint32_t L, split, table_stride, shift0, scale0, shift1, scale1;
  } p{uint32_t(rows), uint32_t(D), eps, 1, 0, 0, 0, 0, 0, 0};
  if (mod) {
    expect_dtype(op, "modulation table", mod->table, DType::f32);
    if (mod->table.rank() != 2 || mod->seq_len < 1 || rows % mod->seq_len != 0 ||
        mod->table.dim(0) != rows / mod->seq_len || mod->split < 0 || mod->split > mod->seq_len)
      throw Error("internal: layernorm: modulation table " + mod->table.describe() + " / seq_len " +
                  std::to_string(mod->seq_len) + " / split " + std::to_string(mod->split) + " do not fit " +
                  x.describe());
    const int64_t W = mod->table.dim(1);
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
  const int64_t n4 = vec4 ? D / 4 : D;
  const bool per_invocation = row_per_invocation(rec);
  const uint32_t local = per_invocation ? 64u : row_local(n4);
  const uint32_t cache =
      vec4 && !per_invocation ? uint32_t(std::min<int64_t>(kRowCache, (n4 + local - 1) / local)) : 1u;
  uint32_t spec[] = {local,          code < 0 ? 0u : uint32_t(code), code >= 0 ? 1u : 0u, mod ? 1u : 0u,
                     vec4 ? 1u : 0u, cache,                          per_invocation ? 1u : 0u};
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/layernorm", spec);
  // Unused bindings get a harmless read-only view (x).
  vk::BufferView xv = vec4_view(x), wv = code >= 0 ? vec4_view(weight) : xv, bv = code >= 0 ? vec4_view(bias) : xv;
  vk::BufferView mv = mod ? vec4_view(mod->table) : xv;
  Grid g = grid_1d(rows, per_invocation ? 64 : 1);
  rec.dispatch(pipe, {xv, vec4_view(y), wv, bv, mv}, &p, sizeof p, g.x, g.y, 1, "layernorm");
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
  vk::BufferView xv = vec4_view(x), wv = code >= 0 ? vec4_view(weight) : xv, bv = code >= 0 ? vec4_view(bias) : xv;
  Grid g = grid_1d(rows * heads, 64);
  rec.dispatch(pipe, {xv, vec4_view(y), wv, bv}, &p, sizeof p, g.x, g.y, 1, "head_layernorm");
}

void rmsnorm(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& weight, float eps) {
  const char* op = "rmsnorm";
  check_rows(op, x, y);
  const int64_t D = x.dim(-1), rows = x.numel() / D;
  uint32_t code = weight_code(op, "weight", weight, D);
  struct {
    uint32_t rows, D;
    float eps;
  } p{uint32_t(rows), uint32_t(D), eps};
  const bool vec4 = D % 4 == 0;
  const int64_t n4 = vec4 ? D / 4 : D;
  const bool per_invocation = row_per_invocation(rec);
  const uint32_t local = per_invocation ? 64u : row_local(n4);
  const uint32_t cache =
      vec4 && !per_invocation ? uint32_t(std::min<int64_t>(kRowCache, (n4 + local - 1) / local)) : 1u;
  uint32_t spec[] = {local, code, vec4 ? 1u : 0u, cache, per_invocation ? 1u : 0u};
  Grid g = grid_1d(rows, per_invocation ? 64 : 1);
  rec.dispatch(rec.context().pipelines().get("nn/rmsnorm", spec), {vec4_view(x), vec4_view(y), vec4_view(weight)}, &p,
               sizeof p, g.x, g.y, 1, "rmsnorm");
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
  if (B * C > 65535) throw Error("internal: groupnorm: more than 65535 (batch, channel) planes");
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
  reduce_segments(rec, x, {n_groups, group_len, group_len, group_len, 0}, ReduceMode::mean_var, mean, var, parts);

  struct {
    uint32_t C, S, channels_per_group;
    float eps;
  } p{uint32_t(C), uint32_t(S), uint32_t(C / groups), eps};
  const bool vec4 = S % 4 == 0;
  uint32_t spec[] = {code < 0 ? 0u : uint32_t(code), code >= 0 ? 1u : 0u, silu ? 1u : 0u, vec4 ? 1u : 0u};
  vk::BufferView wv = code >= 0 ? vec4_view(gamma) : x.buffer(), bv = code >= 0 ? vec4_view(beta) : x.buffer();
  const uint32_t per_group = 64 * 16;  // LOCAL * ITEMS of groupnorm_apply.comp (vec4s with VEC4)
  const uint32_t gx = div_up(vec4 ? S / 4 : S, per_group);
  if (gx > 65535) throw Error("internal: groupnorm: planes of " + std::to_string(S) + " elements are too large");
  rec.dispatch(rec.context().pipelines().get("nn/groupnorm_apply", spec),
               {vec4_view(x), vec4_view(y), wv, bv, mean.buffer(), var.buffer()}, &p, sizeof p, gx, uint32_t(B * C), 1,
               "groupnorm_apply");
}

}  // namespace dvs::ops
