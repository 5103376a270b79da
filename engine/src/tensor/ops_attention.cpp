#include "tensor/ops_attention.hpp"

#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_census.hpp"
#include "tensor/ops_attention_flash.hpp"
#include "tensor/ops_attention_plan.hpp"
#include "vk/context.hpp"

// The recording half of ops::attention: the dispatches of a call as tensor/ops_attention_plan.hpp prepared it
// (the texel kernel whole or split, the flash families, the head-padded copies around either).
namespace dvs::ops {

using namespace attention_plan;

namespace {

constexpr uint32_t kScratchSlot = 2;  // Recorder::scratch slots 2 (K/V) and 3 (state); the convolutions use 0 and 1
constexpr uint32_t kPadSlot = 4;      // slots 4..7: head-padded q, k, v and out (head_dim not a multiple of 4)

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

// Records the split path (one batch element at a time) as plan_split() cut it.
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

struct PadPush {
  uint32_t count, heads, d, dp, pad;
  uint32_t src_off, src_stride, dst_off, dst_stride;
};

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
  note_kernel(ctx, "attention", KernelFamily::texel, "nn/attention", {pr.flash.fallback, pr.flash.device_fallback});
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

AttentionOperand fused_qkv_operand(const Tensor& qkv, int which, int64_t heads, int64_t head_dim) {
  if (which < 0 || which > 2) fail("fused_qkv_operand: which must be 0 (q), 1 (k) or 2 (v)");
  int64_t width = heads * head_dim;
  if (qkv.rank() < 1 || qkv.dim(-1) != 3 * width)
    fail("fused QKV tensor " + qkv.describe() + " does not end in 3·H·D = " + std::to_string(3 * width));
  return {qkv, which * width, 3 * width};
}

}  // namespace dvs::ops
