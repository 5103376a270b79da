#include "tensor/ops_attention_plan.hpp"

#include <algorithm>
#include <string>

#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"

namespace dvs::ops::attention_plan {
namespace {

Blocking blocking_for(const vk::DeviceCaps& caps, int64_t head_dim) {
  if (!device_tuning(caps).attention_rows_by_head_dim) return {1, 4};
  if (head_dim <= 16) return {8, 4};
  if (head_dim <= 64) return {4, 4};
  if (head_dim <= 128) return {2, 4};
  return {1, 4};
}
constexpr int64_t kMaxHeadDim = 256;

int64_t div_floor_pos(int64_t a, int64_t b) { return a < 0 ? -1 : a / b; }

// The split path (one batch element at a time): the head group, query rows and keys of one dispatch, and
// whether K and V are first repacked head-major, so that every binding and grid stays within the limits.
AttentionSplit plan_split(const vk::DeviceCaps& caps, const AttentionShape& s, const Geometry& g,
                          const AttentionOptions& opt, const Blocking& blk, VkDeviceSize workspace_bytes) {
  const int64_t D = s.head_dim, D4 = D / 4, Lq = s.q_len, Lk = s.kv_len, H = s.heads;
  const int64_t align = int64_t(binding_alignment(caps)), slack = align / 4;  // worst-case shift, elements
  const int64_t cap_t = int64_t(binding_capacity(caps, 16) / 4) - slack;      // RGBA32F texel window
  const int64_t cap_s = int64_t(binding_capacity(caps, 0) / 4) - slack;       // storage window
  const int64_t cap_r = int64_t(binding_capacity(caps, 4) / 4) - slack;       // R32F texel window (bias, mask)
  const int64_t kvs = std::max(g.ks, g.vs), rpg = int64_t(kWorkgroupSize) * blk.rows;
  auto align_up = [&](int64_t bytes) { return (bytes + align - 1) / align * align; };

  AttentionSplit p;
  p.whole = false;
  // In place when one head's keys (strided through the token-major rows) fit a binding; else head-major.
  p.repack = opt.workspace || (Lk - 1) * kvs + D > cap_t;
  p.keys = p.repack ? cap_t / D : div_floor_pos(cap_t - D, kvs) + 1;
  if (opt.key_mask || opt.bias) p.keys = std::min(p.keys, cap_r);
  p.keys = std::min(p.keys, Lk);
  if (p.keys < Lk && p.keys >= blk.keys) p.keys = p.keys / blk.keys * blk.keys;  // whole softmax blocks: same sums
  if (p.keys < 1) beyond_limits("not even one key of one head fits a binding: head_dim " + std::to_string(D) + ", row stride " +
                       std::to_string(kvs) + " elements");
  const bool key_split = p.keys < Lk;

  int64_t best = 0;
  for (int64_t hg = std::min<int64_t>(H, caps.max_workgroup_count[1]); hg >= 1; --hg) {
    if (p.repack) {
      if ((hg - 1) * Lk * D + p.keys * D > cap_t) continue;
      const int64_t region = align_up(hg * Lk * D * 4);  // bytes of K (and of V) head-major
      if (opt.workspace ? 2 * region + align > int64_t(workspace_bytes)
                        : 2 * region > int64_t(caps.max_memory_allocation_size))
        continue;
    } else if ((p.keys - 1) * kvs + hg * D > cap_t) {
      continue;
    }
    int64_t qc = std::min<int64_t>(Lq, int64_t(caps.max_workgroup_count[0]) * rpg);
    qc = std::min(qc, div_floor_pos(cap_t - hg * D, g.qs) + 1);
    qc = std::min(qc, div_floor_pos(cap_s - hg * D, g.os) + 1);
    if (opt.bias) qc = std::min(qc, div_floor_pos(cap_r - (hg - 1) * Lq * Lk - p.keys, Lk) + 1);
    if (key_split) qc = std::min(qc, cap_s / (hg * (D + 4)));
    if (qc < 1) continue;
    if (qc < Lq && qc >= rpg) qc = qc / rpg * rpg;  // whole workgroups
    if (hg * qc > best) {
      best = hg * qc;
      p.head_group = hg;
      p.q_rows = qc;
    }
  }
  if (best == 0)
    beyond_limits("no split of heads " + std::to_string(H) + " x rows " + std::to_string(Lq) + " x keys " +
                  std::to_string(Lk) + " (head_dim " + std::to_string(D) + ") fits them");
  // As many groups, evened out (48 heads by at most 29: 24 + 24, not 29 + 19): less repack memory.
  p.head_group = div_up(H, div_up(H, p.head_group));
  if (p.repack) {
    // Repack chunks: token rows of the input (one head group's columns) and of every head's output rows.
    int64_t lc = std::min(Lk, div_floor_pos(cap_t - p.head_group * D, kvs) + 1);
    lc = std::min(lc, div_floor_pos(cap_s - (p.head_group - 1) * Lk * D, D));
    lc = std::min<int64_t>(lc, int64_t(max_groups_1d(caps) * kWorkgroupSize) / (p.head_group * D4));
    if (lc < 1) beyond_limits("the K/V repack of " + std::to_string(p.head_group) + " heads fits none of them");
    p.pack_rows = lc;
    if (!opt.workspace) {
      p.kv_scratch_request = uint64_t(2 * align_up(p.head_group * Lk * D * 4));
      p.scratch_bytes += p.kv_scratch_request;
    }
  }
  if (key_split) {
    p.state_scratch_request = uint64_t(p.q_rows * p.head_group * (D + 4) * 4);
    p.scratch_bytes += uint64_t(align_up(p.q_rows * p.head_group * (D + 4) * 4));
  }
  return p;
}

// Whether one dispatch (plus one repack when a workspace is given) stays within the limits in force.
bool fits_whole(const vk::DeviceCaps& caps, const AttentionShape& s, const AttentionOperand* ops[4], const Geometry& g,
                const AttentionOptions& opt, const Blocking& blk) {
  const int64_t width = s.heads * s.head_dim;
  const int64_t rows_per_group = int64_t(kWorkgroupSize) * blk.rows;
  if (div_up(s.q_len, rows_per_group) > caps.max_workgroup_count[0] || s.heads > caps.max_workgroup_count[1] ||
      s.batch > caps.max_workgroup_count[2])
    return false;
  const int64_t lens[4] = {s.q_len, s.kv_len, s.kv_len, s.q_len}, strides[4] = {g.qs, g.ks, g.vs, g.os};
  for (int i = 0; i < 4; ++i) {
    const bool texel = i < 3;
    const uint64_t shift = texel ? ops[i]->t.buffer().offset % kTexelOffsetAlign : 0;
    const uint64_t bytes = uint64_t((s.batch * lens[i] - 1) * strides[i] + ops[i]->column_offset + width) * 4 + shift;
    if (bytes > binding_capacity(caps, texel ? 16 : 0)) return false;
  }
  for (const Tensor* t : {opt.bias, opt.key_mask})
    if (t && uint64_t(t->numel()) * 4 + t->buffer().offset % kTexelOffsetAlign > binding_capacity(caps, 4))
      return false;
  if (opt.workspace) {
    const int64_t count = s.batch * s.heads * s.kv_len * (s.head_dim / 4);
    if (opt.workspace->numel() < 8 * count) return false;  // the whole batch at once: the split path repacks per batch
    const uint64_t shift = opt.workspace->buffer().offset % kTexelOffsetAlign;
    if (uint64_t(8 * count) * 4 + shift > binding_capacity(caps, 16)) return false;
    if (uint64_t(div_up(count, kWorkgroupSize)) > max_groups_1d(caps) || caps.max_workgroup_count[2] < 2) return false;
  }
  return true;
}

int64_t copy_dispatches(const CopyChunk& c, int64_t rows, int64_t heads) {
  return (heads + c.heads - 1) / c.heads * ((rows + c.rows - 1) / c.rows);
}

PadPlan plan_pad(const vk::DeviceCaps& caps, const AttentionShape& s, const Geometry& g) {
  const int64_t D = s.head_dim, Dp = padded_dim(D), B = s.batch, H = s.heads, Lq = s.q_len, Lk = s.kv_len;
  const int64_t align = int64_t(binding_alignment(caps));
  // Each region starts kTexelOffsetAlign-aligned inside its scratch (so that the plan of the attention on it,
  // made on placeholders at offset 0, is what runs): up to that much more per allocation.
  const int64_t alloc =
      int64_t(std::min<uint64_t>(caps.max_memory_allocation_size, INT64_MAX / 2)) - int64_t(kTexelOffsetAlign);
  const int64_t per_head = std::max(Lq, Lk) * Dp * 4;  // bytes of the larger padded region, one head and batch
  PadPlan pp;
  pp.dp = Dp;
  if (H * per_head <= alloc) {  // every head: as many batch elements as fit
    pp.batch = std::min(B, alloc / (H * per_head));
    pp.heads = H;
    pp.q_rows = Lq;
  } else if (per_head <= alloc) {  // one batch element, a head group
    pp.batch = 1;
    pp.heads = alloc / per_head;
    pp.q_rows = Lq;
  } else {  // one head of one batch element, query rows in chunks (the bias rows of one head stay contiguous)
    if (Lk * Dp * 4 > alloc)
      fail("the keys of one head padded to " + std::to_string(Dp) + " columns (" + std::to_string(Lk * Dp * 4) +
           " bytes) do not fit one allocation of " + std::to_string(alloc) + " bytes");
    pp.batch = 1;
    pp.heads = 1;
    pp.q_rows = std::min(Lq, alloc / (Dp * 4));
  }
  // Evened out: the same number of groups, less scratch (48 heads by at most 29: 24 + 24, not 29 + 19).
  pp.batch = div_up(B, div_up(B, pp.batch));
  pp.heads = div_up(H, div_up(H, pp.heads));
  pp.q_rows = div_up(Lq, div_up(Lq, pp.q_rows));
  auto region = [&](int64_t elems) {
    return uint64_t((elems * 4 + int64_t(kTexelOffsetAlign) + align - 1) / align * align);
  };
  const int64_t W = pp.heads * Dp;
  pp.bytes = 2 * region(pp.batch * pp.q_rows * W) + 2 * region(pp.batch * Lk * W);
  for_each_group(s, pp, [&](int64_t, int64_t bn, int64_t, int64_t hn, int64_t, int64_t qn) {
    const int64_t w = hn * Dp;
    for_each_q_run(0, bn, Lq, 0, qn, [&](int64_t, int64_t, int64_t n) {
      pp.copies += copy_dispatches(copy_chunk(caps, n, hn, g.qs, D, w, Dp), n, hn);   // q in
      pp.copies += copy_dispatches(copy_chunk(caps, n, hn, w, Dp, g.os, D), n, hn);   // out back
    });
    for (int64_t kvs : {g.ks, g.vs})  // k, v in
      pp.copies += copy_dispatches(copy_chunk(caps, bn * Lk, hn, kvs, D, w, Dp), bn * Lk, hn);
  });
  return pp;
}

// A tensor over a placeholder buffer handle: planning reads sizes and offsets, never binds.
Tensor placeholder(const Shape& shape) {
  vk::BufferView v;
  v.buffer = reinterpret_cast<VkBuffer>(uintptr_t(1));
  v.size = VkDeviceSize(std::max<int64_t>(shape_numel(shape), 1)) * 4;
  return Tensor::on(v, shape, DType::f32);
}

void check_options(const AttentionShape& s, const AttentionOptions& opt) {
  if (opt.bias) {
    expect_dtype("attention", "bias", *opt.bias, DType::f32);
    expect_shape("attention", "bias", *opt.bias, {s.heads, s.q_len, s.kv_len});
    if (opt.bias->numel() > int64_t(UINT32_MAX)) fail("bias too large to index");
  }
  if (opt.key_mask) {
    expect_dtype("attention", "key_mask", *opt.key_mask, DType::f32);
    expect_shape("attention", "key_mask", *opt.key_mask, {s.batch, s.kv_len});
  }
  if (opt.workspace) {
    expect_dtype("attention", "workspace", *opt.workspace, DType::f32);
    if (opt.workspace->numel() < attention_workspace_elements(s))
      fail("workspace " + opt.workspace->describe() + " is smaller than the " +
           std::to_string(attention_workspace_elements(s)) + " elements needed");
  }
}

void check_sizes(const AttentionShape& s) {
  if (s.head_dim < 1 || s.head_dim > kMaxHeadDim)
    fail("head_dim " + std::to_string(s.head_dim) + " is not supported: it must be from 1 to " +
         std::to_string(kMaxHeadDim) + " (the kernel keeps a query row's head in registers)");
  if (s.batch < 0 || s.heads < 1 || s.q_len < 0 || s.kv_len < 0) fail("negative or zero size");
  if (s.kv_len == 0 && s.batch > 0 && s.q_len > 0) fail("no keys (kv_len = 0): softmax over nothing is undefined");
}

}  // namespace

int64_t padded_dim(int64_t head_dim) { return (head_dim + 3) / 4 * 4; }

[[noreturn]] void fail(const std::string& what) { throw Error("internal: attention: " + what); }
[[noreturn]] void beyond_limits(const std::string& what) {
  throw Error("attention does not fit this device's limits: " + what +
                  " (maxStorageBufferRange, maxTexelBufferElements, maxMemoryAllocationSize, or DVS_LIMITS where set)."
                  " A device with larger limits runs it",
              ErrorKind::device);
}

void check_operand(const char* name, const AttentionOperand& a, int64_t batch, int64_t len, int64_t width,
                   bool vec4, bool half_ok) {
  if (!a.t.defined()) fail(std::string(name) + " is not given");
  if (!(half_ok && a.t.dtype() == DType::f16)) expect_dtype("attention", name, a.t, DType::f32);
  // Read and written in groups of 4 elements from (aligned-down) windows: the shift must be whole groups.
  const uint64_t elem = dtype_size(a.t.dtype());
  if (vec4 && a.t.buffer().offset % (4 * elem))
    fail(std::string(name) + " starts at a byte offset that is not a multiple of " + std::to_string(4 * elem));
  if (a.t.buffer().offset % elem)
    fail(std::string(name) + " starts at a byte offset that is not a multiple of " + std::to_string(elem));
  if (a.head_major && (a.column_offset || a.row_stride))
    fail(std::string(name) + " is head-major, with column offset " + std::to_string(a.column_offset) +
         " and row stride " + std::to_string(a.row_stride) + ": a head-major operand is [B, H, L, D] contiguous (both 0)");
  int64_t stride = a.row_stride ? a.row_stride : width;  // head-major: the same B·L·H·D elements
  if (a.column_offset < 0 || stride < 0)
    fail(std::string(name) + ": negative column offset " + std::to_string(a.column_offset) + " or row stride " +
         std::to_string(stride));
  if (vec4 && (a.column_offset % 4 || stride % 4))
    fail(std::string(name) + ": column offset " + std::to_string(a.column_offset) + " and row stride " +
         std::to_string(stride) + " must be non-negative multiples of 4");
  if (a.column_offset + width > stride)
    fail(std::string(name) + ": columns [" + std::to_string(a.column_offset) + ", " +
         std::to_string(a.column_offset + width) + ") do not fit a row stride of " + std::to_string(stride));
  const int64_t need = (batch * len - 1) * stride + a.column_offset + width;  // elements touched, from the start
  if (need > a.t.numel())
    fail(std::string(name) + " is " + a.t.describe() + ": too small for " + std::to_string(batch) + "x" +
         std::to_string(len) + " rows of stride " + std::to_string(stride));
}

CopyChunk copy_chunk(const vk::DeviceCaps& caps, int64_t rows, int64_t heads, int64_t src_stride, int64_t src_w,
                     int64_t dst_stride, int64_t dst_w) {
  const int64_t slack = int64_t(binding_alignment(caps)) / 4;
  const int64_t cap_src = int64_t(binding_capacity(caps, 4) / 4) - slack;
  const int64_t cap_dst = int64_t(binding_capacity(caps, 0) / 4) - slack;
  const int64_t items = int64_t(std::min<uint64_t>(max_groups_1d(caps) * kWorkgroupSize, UINT32_MAX));
  CopyChunk c;
  c.heads = std::min({heads, cap_src / src_w, cap_dst / dst_w, items / dst_w});
  if (c.heads < 1)
    fail("the padding copy of one head (" + std::to_string(src_w) + " -> " + std::to_string(dst_w) +
         " columns) does not fit the limits in force");
  c.rows = std::min({rows, div_floor_pos(cap_src - c.heads * src_w, src_stride) + 1,
                     div_floor_pos(cap_dst - c.heads * dst_w, dst_stride) + 1, items / (c.heads * dst_w)});
  return c;
}

AttentionOptions group_options(const AttentionOptions& opt, const AttentionShape& s, int64_t b0, int64_t bn,
                               int64_t h0, int64_t hn, int64_t q0, int64_t qn, Tensor& bias, Tensor& mask) {
  AttentionOptions o = opt;
  if (opt.bias) {
    bias = *opt.bias;
    if (hn < s.heads) bias = bias.rows(h0, hn);
    if (qn < s.q_len) {  // one head at a time (plan_pad)
      if (hn != 1) fail("query rows split over a group of several heads");
      bias = bias.reshape({s.q_len, s.kv_len}).rows(q0, qn).reshape({1, qn, s.kv_len});
    }
    o.bias = &bias;
  }
  if (opt.key_mask) {
    mask = bn < s.batch ? opt.key_mask->rows(b0, bn) : *opt.key_mask;
    o.key_mask = &mask;
  }
  return o;
}

namespace {
// Whether any operand is f16 or head-major: what only the flash kernels take.
bool flash_only_operands(const AttentionOperand& q, const AttentionOperand& k, const AttentionOperand& v,
                         const AttentionOperand& out) {
  for (const AttentionOperand* a : {&q, &k, &v, &out})
    if (a->head_major || (a->t.defined() && a->t.dtype() == DType::f16)) return true;
  return false;
}
}  // namespace

Prepared prepare_aligned(const vk::DeviceCaps& caps, const AttentionShape& s, const AttentionOperand& q,
                         const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                         const AttentionOptions& opt) {
  Prepared pr;
  pr.blk = blocking_for(caps, s.head_dim);
  if (opt.rows_per_invocation) {
    if (opt.rows_per_invocation > 16) fail("rows_per_invocation must be at most 16");
    pr.blk.rows = opt.rows_per_invocation;
  }
  if (s.batch == 0 || s.q_len == 0) return pr;
  const int64_t width = s.heads * s.head_dim;
  check_operand("q", q, s.batch, s.q_len, width, true, true);
  check_operand("k", k, s.batch, s.kv_len, width, true, true);
  check_operand("v", v, s.batch, s.kv_len, width, true, true);
  check_operand("out", out, s.batch, s.q_len, width, true, true);
  if (k.t.dtype() != v.t.dtype()) fail("k is " + k.t.describe() + " and v " + v.t.describe() + ": one dtype for both");
  if (out.head_major) fail("out is head-major: the kernels write it token-major (the next GEMM's rows)");
  check_options(s, opt);
  auto stride_of = [&](const AttentionOperand& a) { return a.row_stride ? a.row_stride : width; };
  pr.geo = {stride_of(q), stride_of(k), stride_of(v), stride_of(out)};
  const AttentionOperand* all[4] = {&q, &k, &v, &out};
  const int64_t strides[4] = {pr.geo.qs, pr.geo.ks, pr.geo.vs, pr.geo.os};
  pr.flash = flash::plan(caps, s, all, strides, opt);
  pr.split.family = pr.flash.family;
  if (flash_only_operands(q, k, v, out) && pr.flash.family == KernelFamily::texel)
    fail("an f16 or head-major operand is taken by the tiled and tensor-core kernels only, and this call runs the "
         "texel kernel" +
         (pr.flash.fallback.empty() ? std::string(" (DeviceTuning::attention)") : " (" + pr.flash.fallback + ")") +
         "; ask attention_takes_f16() first");
  if (pr.flash.family != KernelFamily::texel) return pr;  // one dispatch, nothing cut (split stays whole)
  if (!fits_whole(caps, s, all, pr.geo, opt, pr.blk))
    pr.split = plan_split(caps, s, pr.geo, opt, pr.blk, opt.workspace ? VkDeviceSize(opt.workspace->numel()) * 4 : 0);
  return pr;
}

Prepared prepare(const vk::DeviceCaps& caps, const AttentionShape& s, const AttentionOperand& q,
                 const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                 const AttentionOptions& opt) {
  check_sizes(s);
  if (s.head_dim % 4 == 0) return prepare_aligned(caps, s, q, k, v, out, opt);
  if (opt.rows_per_invocation > 16) fail("rows_per_invocation must be at most 16");
  Prepared pr;
  pr.pad.dp = padded_dim(s.head_dim);
  if (s.batch == 0 || s.q_len == 0) return pr;
  const int64_t width = s.heads * s.head_dim;
  check_operand("q", q, s.batch, s.q_len, width, false);
  check_operand("k", k, s.batch, s.kv_len, width, false);
  check_operand("v", v, s.batch, s.kv_len, width, false);
  if (flash_only_operands(q, k, v, out))
    fail("an f16 or head-major operand needs a head_dim that is a multiple of 4 (head_dim " +
         std::to_string(s.head_dim) + " runs on padded f32 token-major copies); ask attention_takes_f16() first");
  check_operand("out", out, s.batch, s.q_len, width, false);
  check_options(s, opt);
  auto stride_of = [&](const AttentionOperand& a) { return a.row_stride ? a.row_stride : width; };
  pr.geo = {stride_of(q), stride_of(k), stride_of(v), stride_of(out)};
  pr.pad = plan_pad(caps, s, pr.geo);
  const PadPlan& pp = pr.pad;
  // The first (largest) group's attention, planned on placeholders laid out as its padded scratch.
  const AttentionShape gs{pp.batch, pp.heads, pp.dp, pp.q_rows, s.kv_len};
  const int64_t W = pp.heads * pp.dp;
  Tensor bias, mask;
  const AttentionOptions go = group_options(opt, s, 0, pp.batch, 0, pp.heads, 0, pp.q_rows, bias, mask);
  const Prepared inner = prepare_aligned(caps, gs, {placeholder({gs.batch, gs.q_len, W})},
                                         {placeholder({gs.batch, gs.kv_len, W})},
                                         {placeholder({gs.batch, gs.kv_len, W})},
                                         {placeholder({gs.batch, gs.q_len, W})}, go);
  pr.blk = inner.blk;
  pr.split = inner.split;
  const bool one_group = pp.batch == s.batch && pp.heads == s.heads && pp.q_rows == s.q_len;
  pr.split.whole = inner.split.whole && one_group && pp.copies == 4;
  pr.split.scratch_bytes += pp.bytes;
  pr.split.padded_head_dim = pp.dp;
  pr.split.pad_batch = pp.batch;
  pr.split.pad_heads = pp.heads;
  pr.split.pad_q_rows = pp.q_rows;
  pr.split.pad_copies = pp.copies;
  return pr;
}

}  // namespace dvs::ops::attention_plan

namespace dvs::ops {

AttentionSplit attention_split_plan(const vk::DeviceCaps& caps, const AttentionShape& shape, const AttentionOperand& q,
                                    const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                                    const AttentionOptions& options) {
  return attention_plan::prepare(caps, shape, q, k, v, out, options).split;
}

AttentionSplit attention_split_plan_fused(const vk::DeviceCaps& caps, const AttentionShape& s, bool bias,
                                          bool key_mask) {
  // Placeholder views at offset 0 with the operands' sizes: planning reads sizes and offsets, never binds.
  const int64_t width = s.heads * s.head_dim;
  using attention_plan::placeholder;
  const Tensor qkv = placeholder({s.batch, s.q_len, 3 * width}), out = placeholder({s.batch, s.q_len, width});
  const Tensor tbias = placeholder({s.heads, s.q_len, s.kv_len}), tmask = placeholder({s.batch, s.kv_len});
  AttentionOptions opt;
  if (bias) opt.bias = &tbias;
  if (key_mask) opt.key_mask = &tmask;
  return attention_split_plan(caps, s, fused_qkv_operand(qkv, 0, s.heads, s.head_dim),
                              fused_qkv_operand(qkv, 1, s.heads, s.head_dim),
                              fused_qkv_operand(qkv, 2, s.heads, s.head_dim), AttentionOperand{out}, opt);
}

bool attention_takes_f16(const vk::DeviceCaps& caps, const AttentionShape& s, const AttentionOperand& q,
                         const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                         const AttentionOptions& options) {
  if (s.head_dim % 4 != 0) return false;
  return attention_split_plan(caps, s, q, k, v, out, options).family != KernelFamily::texel;
}

AttentionSplit attention_split_plan_contiguous(const vk::DeviceCaps& caps, const AttentionShape& s) {
  const int64_t width = s.heads * s.head_dim;
  using attention_plan::placeholder;
  const Tensor q = placeholder({s.batch, s.q_len, width}), kv = placeholder({s.batch, s.kv_len, width});
  return attention_split_plan(caps, s, AttentionOperand{q}, AttentionOperand{kv}, AttentionOperand{kv},
                              AttentionOperand{q});
}

int64_t attention_workspace_elements(const AttentionShape& s) {
  // One batch element's K and V (the split path repacks one at a time), plus room to align both; a head_dim
  // that is not a multiple of 4 is repacked padded.
  return 2 * s.heads * s.kv_len * attention_plan::padded_dim(s.head_dim) +
         2 * int64_t(attention_plan::kTexelOffsetAlign / 4);
}

bool attention_workspace_helps(const vk::DeviceCaps& caps, const AttentionShape& s) {
  // Measured: no change at H ≤ 2 or short sequences, +15% at H=8/L=1024, ×1.8 at H=48/L=2048.
  // Whether the device wants it at all is its tuning (DeviceTuning::attention_kv_workspace: CPU drivers).
  return device_tuning(caps).attention_kv_workspace && s.heads >= 4 && s.kv_len >= 512;
}

}  // namespace dvs::ops
