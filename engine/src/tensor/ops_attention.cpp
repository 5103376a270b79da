#include "tensor/ops_attention.hpp"

#include <algorithm>
#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_attention_flash.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

// Register blocking of shaders/nn/attention.comp (64 invocations per workgroup, each owning `rows` query rows,
// keys taken `keys` at a time). On CPU devices (lavapipe) every texel fetch is a per-lane loop, so each
// fetched K/V chunk should feed several rows: about 512 floats of q rows and accumulators per invocation
// measured best (more rows spill more than they save; keys 4 and 8 per block run alike, 4 compiles faster).
// GPUs keep one row per invocation (registers are the limit there). Heads over 128 (up to 64 vec4s of q and
// of accumulators per row) keep one row per invocation everywhere. Which applies is the device's tuning
// (DeviceTuning::attention_rows_by_head_dim).
struct Blocking {
  uint32_t rows, keys;
};
Blocking blocking_for(const vk::DeviceCaps& caps, int64_t head_dim) {
  if (!device_tuning(caps).attention_rows_by_head_dim) return {1, 4};
  if (head_dim <= 16) return {8, 4};
  if (head_dim <= 64) return {4, 4};
  if (head_dim <= 128) return {2, 4};
  return {1, 4};
}
constexpr int64_t kMaxHeadDim = 256;
constexpr uint32_t kWorkgroupSize = 64;
constexpr VkDeviceSize kTexelOffsetAlign = 256;  // the largest minTexelBufferOffsetAlignment Vulkan allows
constexpr uint32_t kScratchSlot = 2;  // Recorder::scratch slots 2 (K/V) and 3 (state); the convolutions use 0 and 1
constexpr uint32_t kPadSlot = 4;      // slots 4..7: head-padded q, k, v and out (head_dim not a multiple of 4)

int64_t padded_dim(int64_t head_dim) { return (head_dim + 3) / 4 * 4; }

[[noreturn]] void fail(const std::string& what) { throw Error("internal: attention: " + what); }

// A bound window of elements [first, first + count) of a buffer, started at the aligned-down offset; the
// skipped elements (shift) go to the shader as an element offset.
struct Window {
  vk::BufferView view;
  uint32_t shift = 0;  // elements
};
Window window(const vk::BufferView& base, int64_t first, int64_t count, uint64_t align) {
  const VkDeviceSize start = base.offset + VkDeviceSize(first) * 4, shift = start % align;
  Window w;
  w.view = {base.buffer, start - shift, VkDeviceSize(count) * 4 + shift,
            base.mapped ? base.mapped + (int64_t(start - shift) - int64_t(base.offset)) : nullptr};
  w.shift = uint32_t(shift / 4);
  return w;
}

// A q/k/v/out operand checked against the shape, as a binding plus offset/stride in vec4 units.
struct Bound {
  vk::BufferView view;
  uint32_t off4 = 0, stride4 = 0;
};

// Validates an operand against the shape: defined f32, aligned columns inside the row stride, large enough.
// `vec4`: read or written in place as vec4s (head_dim a multiple of 4); else only copied element-wise.
void check_operand(const char* name, const AttentionOperand& a, int64_t batch, int64_t len, int64_t width,
                   bool vec4 = true) {
  if (!a.t.defined()) fail(std::string(name) + " is not given");
  expect_dtype("attention", name, a.t, DType::f32);
  // Read and written as vec4s from (aligned-down) windows: the shift must be whole vec4s.
  if (vec4 && a.t.buffer().offset % 16)
    fail(std::string(name) + " starts at a byte offset that is not a multiple of 16");
  if (a.t.buffer().offset % 4) fail(std::string(name) + " starts at a byte offset that is not a multiple of 4");
  int64_t stride = a.row_stride ? a.row_stride : width;
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

Bound bind_operand(const char* name, const AttentionOperand& a, int64_t batch, int64_t len, int64_t width,
                   bool texel) {
  check_operand(name, a, batch, len, width);
  const int64_t stride = a.row_stride ? a.row_stride : width;
  const int64_t need = (batch * len - 1) * stride + a.column_offset + width;
  // Texel views must start at an aligned offset: start earlier and shift the columns instead.
  const Window w = window(a.t.buffer(), 0, need, texel ? kTexelOffsetAlign : 1);
  if ((need + int64_t(w.shift)) / 4 > int64_t(UINT32_MAX)) fail(std::string(name) + " is too large to index");
  Bound b;
  b.view = w.view;
  b.off4 = uint32_t((a.column_offset + int64_t(w.shift)) / 4);
  b.stride4 = uint32_t(stride / 4);
  return b;
}


struct PackPush {
  uint32_t count, rows, heads, d4;
  uint32_t k_off, k_stride, v_off, v_stride;
  uint32_t out_len, pk_off, pv_off;
};

// ---- the split path: one batch element at a time ----

struct Geometry {  // the operand strides of a call, elements
  int64_t qs, ks, vs, os;
};

int64_t div_floor_pos(int64_t a, int64_t b) { return a < 0 ? -1 : a / b; }

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
  if (p.keys < 1) fail("not even one key of one head fits a binding: head_dim " + std::to_string(D) + ", row stride " +
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
    fail("no split of heads " + std::to_string(H) + " x rows " + std::to_string(Lq) + " x keys " + std::to_string(Lk) +
         " (head_dim " + std::to_string(D) + ") fits the limits in force");
  // As many groups, evened out (48 heads by at most 29: 24 + 24, not 29 + 19): less repack memory.
  p.head_group = div_up(H, div_up(H, p.head_group));
  if (p.repack) {
    // Repack chunks: token rows of the input (one head group's columns) and of every head's output rows.
    int64_t lc = std::min(Lk, div_floor_pos(cap_t - p.head_group * D, kvs) + 1);
    lc = std::min(lc, div_floor_pos(cap_s - (p.head_group - 1) * Lk * D, D));
    lc = std::min<int64_t>(lc, int64_t(max_groups_1d(caps) * kWorkgroupSize) / (p.head_group * D4));
    if (lc < 1) fail("the K/V repack of " + std::to_string(p.head_group) + " heads does not fit the limits in force");
    p.pack_rows = lc;
    if (!opt.workspace) p.scratch_bytes += uint64_t(2 * align_up(p.head_group * Lk * D * 4));
  }
  if (key_split) p.scratch_bytes += uint64_t(align_up(p.q_rows * p.head_group * (D + 4) * 4));
  return p;
}

void attention_split(vk::Recorder& rec, const AttentionShape& s, const AttentionOperand& q, const AttentionOperand& k,
                     const AttentionOperand& v, const AttentionOperand& out, const AttentionOptions& opt,
                     const Blocking& blk, const Geometry& g, const AttentionSplit& p) {
  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  const int64_t D = s.head_dim, D4 = D / 4, Lq = s.q_len, Lk = s.kv_len, H = s.heads;
  const uint64_t align = binding_alignment(caps);
  const int64_t rpg = int64_t(kWorkgroupSize) * blk.rows;
  const VkFormat rgba = VK_FORMAT_R32G32B32A32_SFLOAT, r32 = VK_FORMAT_R32_SFLOAT;

  // Head-major K and V of one head group: [hg, Lk, D] each, in the workspace or a recording scratch.
  const VkDeviceSize region = (VkDeviceSize(p.head_group * Lk * D) * 4 + align - 1) / align * align;
  vk::BufferView kreg, vreg;
  if (p.repack) {
    vk::BufferView ws = opt.workspace ? opt.workspace->buffer()
                                      : rec.scratch(kScratchSlot, 2 * region, "attention K/V (head-major)");
    const VkDeviceSize lead = (align - ws.offset % align) % align;
    kreg = {ws.buffer, ws.offset + lead, region, ws.mapped ? ws.mapped + lead : nullptr};
    vreg = {ws.buffer, kreg.offset + region, region, ws.mapped ? kreg.mapped + region : nullptr};
  }

  for (int64_t b = 0; b < s.batch; ++b) {
    for_each_chunk(H, p.head_group, [&](int64_t h0, int64_t hn) {
      // Rows [row0, row0 + n) of batch element b, heads [h0, h0 + hn), of a token-major operand.
      auto rows = [&](const AttentionOperand& a, int64_t stride, int64_t len, int64_t row0, int64_t n) {
        return window(a.t.buffer(), (b * len + row0) * stride + a.column_offset + h0 * D, (n - 1) * stride + hn * D,
                      align);
      };
      // Keys [key0, key0 + n) of every head of the group, head-major.
      auto keys = [&](const vk::BufferView& region, int64_t key0, int64_t n) {
        return window(region, key0 * D, (hn - 1) * Lk * D + n * D, align);
      };
      if (p.repack) {
        for_each_chunk(Lk, p.pack_rows, [&](int64_t l0, int64_t ln) {
          const Window ki = rows(k, g.ks, Lk, l0, ln), vi = rows(v, g.vs, Lk, l0, ln);
          const Window ko = keys(kreg, l0, ln), vo = keys(vreg, l0, ln);
          PackPush pp{uint32_t(hn * ln * D4), uint32_t(ln),      uint32_t(hn), uint32_t(D4),
                      ki.shift / 4,           uint32_t(g.ks / 4), vi.shift / 4, uint32_t(g.vs / 4),
                      uint32_t(Lk),           ko.shift / 4,       vo.shift / 4};
          const Grid gr = grid_1d(caps, hn * ln * D4, kWorkgroupSize);
          rec.dispatch(ctx.pipelines().get("nn/attention_pack"),
                       {vk::Binding(ki.view, rgba), vk::Binding(vi.view, rgba), ko.view, vo.view}, &pp, sizeof pp,
                       gr.x, gr.y, 2, "attention_pack");
        });
      }
      for_each_chunk(Lq, p.q_rows, [&](int64_t q0, int64_t qn) {
        const Window qw = rows(q, g.qs, Lq, q0, qn), ow = rows(out, g.os, Lq, q0, qn);
        vk::BufferView state = ow.view;  // bound but unused unless the keys are split
        if (p.keys < Lk)
          state = rec.scratch(kScratchSlot + 1, VkDeviceSize(qn * hn * (D + 4)) * 4, "attention running state");
        for_each_chunk(Lk, p.keys, [&](int64_t k0, int64_t kn) {
          Window kw, vw;
          AttentionPush push{};
          push.q_len = uint32_t(qn);
          push.kv_len = uint32_t(kn);
          push.heads = uint32_t(hn);
          push.q_off = qw.shift / 4;
          push.q_stride = uint32_t(g.qs / 4);
          push.o_off = ow.shift / 4;
          push.o_stride = uint32_t(g.os / 4);
          if (p.repack) {
            kw = keys(kreg, k0, kn);
            vw = keys(vreg, k0, kn);
            push.k_stride = push.v_stride = uint32_t(D4);
            push.k_hstride = push.v_hstride = uint32_t(Lk * D4);
          } else {
            kw = rows(k, g.ks, Lk, k0, kn);
            vw = rows(v, g.vs, Lk, k0, kn);
            push.k_stride = uint32_t(g.ks / 4);
            push.v_stride = uint32_t(g.vs / 4);
            push.k_hstride = push.v_hstride = uint32_t(D4);
          }
          push.k_off = kw.shift / 4;
          push.v_off = vw.shift / 4;
          push.scale = opt.scale;
          vk::Binding bias(qw.view.sub(0, 16), r32), mask(qw.view.sub(0, 16), r32);
          if (opt.bias) {
            const Window bw =
                window(opt.bias->buffer(), (h0 * Lq + q0) * Lk + k0, (hn - 1) * Lq * Lk + (qn - 1) * Lk + kn, align);
            bias = vk::Binding(bw.view, r32);
            push.bias_off = bw.shift;
            push.bias_hstride = uint32_t(Lq * Lk);
            push.bias_rstride = uint32_t(Lk);
          }
          if (opt.key_mask) {
            const Window mw = window(opt.key_mask->buffer(), b * Lk + k0, kn, align);
            mask = vk::Binding(mw.view, r32);
            push.mask_off = mw.shift;
          }
          const uint32_t spec[] = {uint32_t(D4), opt.bias ? 1u : 0u, opt.key_mask ? 1u : 0u, blk.rows, blk.keys,
                                   k0 > 0 ? 1u : 0u, k0 + kn < Lk ? 1u : 0u};
          rec.dispatch(ctx.pipelines().get("nn/attention", spec),
                       {vk::Binding(qw.view, rgba), vk::Binding(kw.view, rgba), vk::Binding(vw.view, rgba), ow.view,
                        bias, mask, state},
                       &push, sizeof push, uint32_t(div_up(qn, rpg)), uint32_t(hn), 1, "attention");
        });
      });
    });
  }
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

// ---- head_dim not a multiple of 4: padded copies (shaders/nn/attention_pad.comp) ----

// A head-padded call runs in groups: batch elements × heads × query rows whose padded copies each fit one
// allocation (Recorder scratch slots kPadSlot..kPadSlot + 3).
struct PadPlan {
  int64_t dp = 0;                            // padded head_dim; 0: no padding
  int64_t batch = 0, heads = 0, q_rows = 0;  // one group
  int64_t copies = 0;                        // copy dispatches of the whole call
  uint64_t bytes = 0;                        // the four padded regions of one (the largest) group
};

struct PadPush {
  uint32_t count, heads, d, dp, pad;
  uint32_t src_off, src_stride, dst_off, dst_stride;
};

// The most heads × token rows one copy dispatch may cover: the source window (R32F texels) and the
// destination window (storage) each within one binding (with the worst-case alignment shift), the
// elements written within one grid. Widths are columns per head, strides elements per token row.
struct CopyChunk {
  int64_t heads = 0, rows = 0;
};
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
int64_t copy_dispatches(const CopyChunk& c, int64_t rows, int64_t heads) {
  return (heads + c.heads - 1) / c.heads * ((rows + c.rows - 1) / c.rows);
}

// fn(b0, bn, h0, hn, q0, qn) for every group of a padded call.
template <class F>
void for_each_group(const AttentionShape& s, const PadPlan& pp, F&& fn) {
  for_each_chunk(s.batch, pp.batch, [&](int64_t b0, int64_t bn) {
    for_each_chunk(s.heads, pp.heads, [&](int64_t h0, int64_t hn) {
      for_each_chunk(s.q_len, pp.q_rows, [&](int64_t q0, int64_t qn) { fn(b0, bn, h0, hn, q0, qn); });
    });
  });
}

// The query (and output) token rows of a group as runs of consecutive rows: fn(model_row0, padded_row0, n).
// One run of bn·Lq rows when the group has every query row, else one run of qn rows per batch element.
template <class F>
void for_each_q_run(int64_t b0, int64_t bn, int64_t q_len, int64_t q0, int64_t qn, F&& fn) {
  if (qn == q_len) return fn(b0 * q_len, int64_t(0), bn * q_len);
  for (int64_t b = 0; b < bn; ++b) fn((b0 + b) * q_len + q0, b * qn, qn);
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

// The options of one group's padded call: the bias rows of its heads (and query rows), the mask rows of its
// batch elements. `bias` and `mask` hold the views the returned options point to.
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

// A tensor over a placeholder buffer handle: planning reads sizes and offsets, never binds.
Tensor placeholder(const Shape& shape) {
  vk::BufferView v;
  v.buffer = reinterpret_cast<VkBuffer>(uintptr_t(1));
  v.size = VkDeviceSize(std::max<int64_t>(shape_numel(shape), 1)) * 4;
  return Tensor::on(v, shape, DType::f32);
}

// ---- validation and planning ----

// Validates a call and decides how it runs.
struct Prepared {
  Blocking blk{1, 4};
  flash::Plan flash;  // family texel: attention.comp (with its split paths) runs the call
  Geometry geo{};
  AttentionSplit split;
  PadPlan pad;  // pad.dp > 0: head_dim is padded (pad.copies == 0 when there is nothing to do)
};

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

// A call whose head_dim is a multiple of 4: the kernel reads the operands in place.
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
  check_operand("q", q, s.batch, s.q_len, width);
  check_operand("k", k, s.batch, s.kv_len, width);
  check_operand("v", v, s.batch, s.kv_len, width);
  check_operand("out", out, s.batch, s.q_len, width);
  check_options(s, opt);
  auto stride_of = [&](const AttentionOperand& a) { return a.row_stride ? a.row_stride : width; };
  pr.geo = {stride_of(q), stride_of(k), stride_of(v), stride_of(out)};
  const AttentionOperand* all[4] = {&q, &k, &v, &out};
  const int64_t strides[4] = {pr.geo.qs, pr.geo.ks, pr.geo.vs, pr.geo.os};
  pr.flash = flash::plan(caps, s, all, strides, opt);
  pr.split.family = pr.flash.family;
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

// ---- recording ----

// Records a call prepared by prepare_aligned (head_dim a multiple of 4, nothing empty).
void attention_aligned(vk::Recorder& rec, const AttentionShape& s, const AttentionOperand& q,
                       const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                       const AttentionOptions& opt, const Prepared& pr) {
  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  if (pr.flash.family != KernelFamily::texel) {
    const AttentionOperand* all[4] = {&q, &k, &v, &out};
    const int64_t strides[4] = {pr.geo.qs, pr.geo.ks, pr.geo.vs, pr.geo.os};
    return flash::record(rec, s, all, strides, opt, pr.flash);
  }
  if (!pr.split.whole) return attention_split(rec, s, q, k, v, out, opt, pr.blk, pr.geo, pr.split);
  const Blocking blk = pr.blk;
  const int64_t width = s.heads * s.head_dim, rows_per_group = int64_t(kWorkgroupSize) * blk.rows;

  Bound bq = bind_operand("q", q, s.batch, s.q_len, width, true);
  Bound bk = bind_operand("k", k, s.batch, s.kv_len, width, true);
  Bound bv = bind_operand("v", v, s.batch, s.kv_len, width, true);
  Bound bo = bind_operand("out", out, s.batch, s.q_len, width, false);

  const uint32_t spec[] = {uint32_t(s.head_dim / 4), opt.bias ? 1u : 0u, opt.key_mask ? 1u : 0u, blk.rows, blk.keys,
                           0u, 0u};  // no state: all keys in this dispatch
  const vk::Pipeline& pipe = ctx.pipelines().get("nn/attention", spec);

  const uint32_t d4 = uint32_t(s.head_dim / 4), kv_len = uint32_t(s.kv_len);
  AttentionPush push{uint32_t(s.q_len), kv_len, uint32_t(s.heads), bq.off4, bq.stride4, bo.off4, bo.stride4,
            // k and v token-major: batch stride Lk rows, head stride D
            bk.off4, bk.stride4, kv_len * bk.stride4, d4, bv.off4, bv.stride4, kv_len * bv.stride4, d4,
            opt.scale, 0, uint32_t(s.q_len * s.kv_len), kv_len, 0};
  const VkFormat rgba = VK_FORMAT_R32G32B32A32_SFLOAT;
  vk::Binding k_binding(bk.view, rgba), v_binding(bv.view, rgba);

  if (opt.workspace) {
    // Repack K and V head-major [B, H, Lk, D] (K then V) and read them from there.
    const int64_t count = s.batch * s.heads * s.kv_len * int64_t(d4);  // vec4s per tensor
    if (2 * count > int64_t(UINT32_MAX)) fail("workspace too large to index");
    vk::BufferView ws = opt.workspace->buffer();
    ws.size = VkDeviceSize(2 * count) * 16;
    Bound bw = bind_operand("workspace", {*opt.workspace, 0, 4}, 1, 2 * count, 4, true);  // as 2·count vec4 rows
    PackPush pp{uint32_t(count), kv_len, uint32_t(s.heads), d4, bk.off4, bk.stride4, bv.off4, bv.stride4,
                kv_len, 0, uint32_t(count)};
    Grid g = grid_1d(caps, count, kWorkgroupSize);
    rec.dispatch(ctx.pipelines().get("nn/attention_pack"), {k_binding, v_binding, ws, ws}, &pp, sizeof pp, g.x, g.y, 2,
                 "attention_pack");
    k_binding = vk::Binding(bw.view, rgba);
    v_binding = vk::Binding(bw.view, rgba);
    const uint32_t head4 = kv_len * d4;
    push.k_off = bw.off4;
    push.k_stride = d4;
    push.k_hstride = head4;
    push.k_bstride = uint32_t(s.heads) * head4;
    push.v_off = bw.off4 + uint32_t(count);
    push.v_stride = d4;
    push.v_hstride = head4;
    push.v_bstride = uint32_t(s.heads) * head4;
  }

  // Bias and mask are read as R32F texels; their views start at an aligned offset (the shift goes to the
  // shader). Unused ones are bound to the first texel of q and never read.
  auto scalar_texels = [&](const Tensor* t, const char* name, uint32_t& shift_elems) {
    shift_elems = 0;
    if (!t) return vk::Binding(bq.view.sub(0, 16), VK_FORMAT_R32_SFLOAT);
    if (t->buffer().offset % 4) fail(std::string(name) + " is not 4-byte aligned");
    const Window w = window(t->buffer(), 0, t->numel(), kTexelOffsetAlign);
    shift_elems = w.shift;
    return vk::Binding(w.view, VK_FORMAT_R32_SFLOAT);
  };
  vk::Binding bias_binding = scalar_texels(opt.bias, "bias", push.bias_off);
  vk::Binding mask_binding = scalar_texels(opt.key_mask, "key_mask", push.mask_off);
  rec.dispatch(pipe, {vk::Binding(bq.view, rgba), k_binding, v_binding, bo.view, bias_binding, mask_binding, bo.view},
               &push, sizeof push, div_up(s.q_len, rows_per_group), uint32_t(s.heads), uint32_t(s.batch),
               "attention");
}

// Copies `heads` heads of `rows` token rows between a model layout (head_dim columns per head) and the
// head-padded one (pad: model -> padded; else padded -> model), in chunks within the limits in force.
// Positions are elements: the first row's first head at src_first / dst_first, rows src_stride / dst_stride apart.
void pad_copy(vk::Recorder& rec, bool pad, int64_t D, int64_t Dp, const vk::BufferView& src, int64_t src_first,
              int64_t src_stride, const vk::BufferView& dst, int64_t dst_first, int64_t dst_stride, int64_t rows,
              int64_t heads) {
  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  const uint64_t align = binding_alignment(caps);
  const int64_t src_w = pad ? D : Dp, dst_w = pad ? Dp : D;
  const CopyChunk c = copy_chunk(caps, rows, heads, src_stride, src_w, dst_stride, dst_w);
  for_each_chunk(heads, c.heads, [&](int64_t h0, int64_t hn) {
    for_each_chunk(rows, c.rows, [&](int64_t r0, int64_t rn) {
      const Window sw = window(src, src_first + r0 * src_stride + h0 * src_w, (rn - 1) * src_stride + hn * src_w, align);
      const Window dw = window(dst, dst_first + r0 * dst_stride + h0 * dst_w, (rn - 1) * dst_stride + hn * dst_w, align);
      const int64_t count = rn * hn * dst_w;
      PadPush pp{uint32_t(count),      uint32_t(hn), uint32_t(D), uint32_t(Dp),         pad ? 1u : 0u,
                 sw.shift,             uint32_t(src_stride),      dw.shift,             uint32_t(dst_stride)};
      const Grid g = grid_1d(caps, count, kWorkgroupSize);
      rec.dispatch(ctx.pipelines().get("nn/attention_pad"), {vk::Binding(sw.view, VK_FORMAT_R32_SFLOAT), dw.view},
                   &pp, sizeof pp, g.x, g.y, 1, pad ? "attention_pad" : "attention_unpad");
    });
  });
}

// Records a call prepared with a padded head_dim: per group, q, k, v into head-padded scratch, the attention
// there (head_dim Dp; the logits' scale is options.scale, and the zero columns add nothing), the first D
// columns of each head back into out.
void attention_padded(vk::Recorder& rec, const AttentionShape& s, const AttentionOperand& q,
                      const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                      const AttentionOptions& opt, const Prepared& pr) {
  const vk::DeviceCaps& caps = rec.context().caps();
  const PadPlan& pp = pr.pad;
  const Geometry& g = pr.geo;
  const int64_t D = s.head_dim, Dp = pp.dp, Lq = s.q_len, Lk = s.kv_len;
  for_each_group(s, pp, [&](int64_t b0, int64_t bn, int64_t h0, int64_t hn, int64_t q0, int64_t qn) {
    const int64_t W = hn * Dp;
    const AttentionShape gs{bn, hn, Dp, qn, Lk};
    // Each padded operand starts kTexelOffsetAlign-aligned, as the placeholders prepare() planned on.
    auto scratch = [&](uint32_t i, int64_t len, const char* what) {
      const VkDeviceSize bytes = VkDeviceSize(bn * len * W) * 4;
      vk::BufferView view = rec.scratch(kPadSlot + i, bytes + kTexelOffsetAlign, what);
      const VkDeviceSize lead = (kTexelOffsetAlign - view.offset % kTexelOffsetAlign) % kTexelOffsetAlign;
      return Tensor::on(view.sub(lead, bytes), {bn, len, W}, DType::f32);
    };
    const Tensor tq = scratch(0, qn, "attention q (head-padded)"), tk = scratch(1, Lk, "attention k (head-padded)");
    const Tensor tv = scratch(2, Lk, "attention v (head-padded)"), to = scratch(3, qn, "attention out (head-padded)");
    for_each_q_run(b0, bn, Lq, q0, qn, [&](int64_t row0, int64_t prow0, int64_t n) {
      pad_copy(rec, true, D, Dp, q.t.buffer(), row0 * g.qs + q.column_offset + h0 * D, g.qs, tq.buffer(), prow0 * W, W,
               n, hn);
    });
    pad_copy(rec, true, D, Dp, k.t.buffer(), b0 * Lk * g.ks + k.column_offset + h0 * D, g.ks, tk.buffer(), 0, W, bn * Lk,
             hn);
    pad_copy(rec, true, D, Dp, v.t.buffer(), b0 * Lk * g.vs + v.column_offset + h0 * D, g.vs, tv.buffer(), 0, W, bn * Lk,
             hn);
    Tensor bias, mask;
    const AttentionOptions go = group_options(opt, s, b0, bn, h0, hn, q0, qn, bias, mask);
    const Prepared inner = prepare_aligned(caps, gs, {tq}, {tk}, {tv}, {to}, go);
    attention_aligned(rec, gs, {tq}, {tk}, {tv}, {to}, go, inner);
    for_each_q_run(b0, bn, Lq, q0, qn, [&](int64_t row0, int64_t prow0, int64_t n) {
      pad_copy(rec, false, D, Dp, to.buffer(), prow0 * W, W, out.t.buffer(), row0 * g.os + out.column_offset + h0 * D,
               g.os, n, hn);
    });
  });
}

}  // namespace

AttentionSplit attention_split_plan(const vk::DeviceCaps& caps, const AttentionShape& shape, const AttentionOperand& q,
                                    const AttentionOperand& k, const AttentionOperand& v, const AttentionOperand& out,
                                    const AttentionOptions& options) {
  return prepare(caps, shape, q, k, v, out, options).split;
}

AttentionSplit attention_split_plan_fused(const vk::DeviceCaps& caps, const AttentionShape& s, bool bias,
                                          bool key_mask) {
  // Placeholder views at offset 0 with the operands' sizes: planning reads sizes and offsets, never binds.
  const int64_t width = s.heads * s.head_dim;
  const Tensor qkv = placeholder({s.batch, s.q_len, 3 * width}), out = placeholder({s.batch, s.q_len, width});
  const Tensor tbias = placeholder({s.heads, s.q_len, s.kv_len}), tmask = placeholder({s.batch, s.kv_len});
  AttentionOptions opt;
  if (bias) opt.bias = &tbias;
  if (key_mask) opt.key_mask = &tmask;
  return attention_split_plan(caps, s, fused_qkv_operand(qkv, 0, s.heads, s.head_dim),
                              fused_qkv_operand(qkv, 1, s.heads, s.head_dim),
                              fused_qkv_operand(qkv, 2, s.heads, s.head_dim), AttentionOperand{out}, opt);
}

void attention(vk::Recorder& rec, const AttentionShape& s, const AttentionOperand& q, const AttentionOperand& k,
               const AttentionOperand& v, const AttentionOperand& out, const AttentionOptions& opt) {
  vk::Context& ctx = rec.context();
  const Prepared pr = prepare(ctx.caps(), s, q, k, v, out, opt);
  if (s.batch == 0 || s.q_len == 0) return;
  if (!pr.split.whole) ctx.note_split("attention");  // once per call, whatever is cut
  if (pr.pad.dp) return attention_padded(rec, s, q, k, v, out, opt, pr);
  attention_aligned(rec, s, q, k, v, out, opt, pr);
}
void attention(vk::Recorder& rec, const Tensor& q, const Tensor& k, const Tensor& v, const Tensor& out,
               int64_t heads, const AttentionOptions& options) {
  if (q.rank() != 3 || k.rank() != 3 || v.rank() != 3 || out.rank() != 3)
    fail("q, k, v, out must be [B, L, H·D]; got " + q.describe() + ", " + k.describe() + ", " + v.describe() +
         ", " + out.describe());
  if (heads < 1 || q.dim(2) % heads) fail("width " + std::to_string(q.dim(2)) + " is not a multiple of the heads");
  AttentionShape s{q.dim(0), heads, q.dim(2) / heads, q.dim(1), k.dim(1)};
  expect_shape("attention", "k", k, {s.batch, s.kv_len, q.dim(2)});
  expect_shape("attention", "v", v, {s.batch, s.kv_len, q.dim(2)});
  expect_shape("attention", "out", out, q.shape());
  attention(rec, s, {q}, {k}, {v}, {out}, options);
}

int64_t attention_workspace_elements(const AttentionShape& s) {
  // One batch element's K and V (the split path repacks one at a time), plus room to align both; a head_dim
  // that is not a multiple of 4 is repacked padded.
  return 2 * s.heads * s.kv_len * padded_dim(s.head_dim) + 2 * int64_t(kTexelOffsetAlign / 4);
}

bool attention_workspace_helps(const vk::DeviceCaps& caps, const AttentionShape& s) {
  // Measured: no change at H ≤ 2 or short sequences, +15% at H=8/L=1024, ×1.8 at H=48/L=2048.
  // Whether the device wants it at all is its tuning (DeviceTuning::attention_kv_workspace: CPU drivers).
  return device_tuning(caps).attention_kv_workspace && s.heads >= 4 && s.kv_len >= 512;
}

AttentionOperand fused_qkv_operand(const Tensor& qkv, int which, int64_t heads, int64_t head_dim) {
  if (which < 0 || which > 2) fail("fused_qkv_operand: which must be 0 (q), 1 (k) or 2 (v)");
  int64_t width = heads * head_dim;
  if (qkv.rank() < 1 || qkv.dim(-1) != 3 * width)
    fail("fused QKV tensor " + qkv.describe() + " does not end in 3·H·D = " + std::to_string(3 * width));
  return {qkv, which * width, 3 * width};
}

}  // namespace dvs::ops
