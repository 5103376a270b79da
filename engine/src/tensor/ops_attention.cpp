#include "tensor/ops_attention.hpp"

#include <string>

#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

// Register blocking of shaders/nn/attention.comp (64 invocations per workgroup, each owning `rows` query rows,
// keys taken `keys` at a time). On CPU devices (lavapipe) every texel fetch is a per-lane loop, so each
// fetched K/V chunk should feed several rows: about 512 floats of q rows and accumulators per invocation
// measured best (more rows spill more than they save; keys 4 and 8 per block run alike, 4 compiles faster).
// GPUs keep one row per invocation (registers are the limit there).
struct Blocking {
  uint32_t rows, keys;
};
Blocking blocking_for(const vk::DeviceCaps& caps, int64_t head_dim) {
  if (caps.type != VK_PHYSICAL_DEVICE_TYPE_CPU) return {1, 4};
  if (head_dim <= 16) return {8, 4};
  if (head_dim <= 64) return {4, 4};
  return {2, 4};
}
constexpr uint32_t kWorkgroupSize = 64;
constexpr VkDeviceSize kTexelOffsetAlign = 256;  // the largest minTexelBufferOffsetAlignment Vulkan allows

[[noreturn]] void fail(const std::string& what) { throw Error("internal: attention: " + what); }

// A q/k/v/out operand checked against the shape, as a binding plus offset/stride in vec4 units.
struct Bound {
  vk::BufferView view;
  uint32_t off4 = 0, stride4 = 0;
};

Bound bind_operand(const char* name, const AttentionOperand& a, int64_t batch, int64_t len, int64_t width,
                   bool texel, const vk::DeviceCaps& caps) {
  if (!a.t.defined()) fail(std::string(name) + " is not given");
  expect_dtype("attention", name, a.t, DType::f32);
  int64_t stride = a.row_stride ? a.row_stride : width;
  if (a.column_offset < 0 || a.column_offset % 4 || stride % 4)
    fail(std::string(name) + ": column offset " + std::to_string(a.column_offset) + " and row stride " +
         std::to_string(stride) + " must be non-negative multiples of 4");
  if (a.column_offset + width > stride)
    fail(std::string(name) + ": columns [" + std::to_string(a.column_offset) + ", " +
         std::to_string(a.column_offset + width) + ") do not fit a row stride of " + std::to_string(stride));
  int64_t need = (batch * len - 1) * stride + a.column_offset + width;  // elements touched, from the start
  if (need > a.t.numel())
    fail(std::string(name) + " is " + a.t.describe() + ": too small for " + std::to_string(batch) + "x" +
         std::to_string(len) + " rows of stride " + std::to_string(stride));
  Bound b;
  vk::BufferView v = a.t.buffer();
  VkDeviceSize bytes = VkDeviceSize(need) * 4;
  VkDeviceSize shift = 0;
  if (texel) {
    // Texel views must start at an aligned offset: start earlier and shift the columns instead.
    shift = v.offset % kTexelOffsetAlign;
    if (shift % 16) fail(std::string(name) + " starts at a byte offset that is not a multiple of 16");
    if ((bytes + shift) / 16 > caps.max_texel_buffer_elements)
      fail(std::string(name) + " spans " + std::to_string((bytes + shift) / 16) +
           " RGBA32F texels, more than this device's maxTexelBufferElements (" +
           std::to_string(caps.max_texel_buffer_elements) + ")");
  }
  b.view.buffer = v.buffer;
  b.view.offset = v.offset - shift;
  b.view.size = bytes + shift;
  b.view.mapped = v.mapped ? v.mapped - shift : nullptr;
  b.off4 = uint32_t((a.column_offset + int64_t(shift / 4)) / 4);
  b.stride4 = uint32_t(stride / 4);
  if ((need + int64_t(shift / 4)) / 4 > int64_t(UINT32_MAX)) fail(std::string(name) + " is too large to index");
  return b;
}

struct Push {
  uint32_t q_len, kv_len, heads;
  uint32_t q_off, q_stride, o_off, o_stride;
  uint32_t k_off, k_stride, k_bstride, k_hstride;
  uint32_t v_off, v_stride, v_bstride, v_hstride;
  float scale;
  uint32_t bias_off, mask_off;  // elements
};

struct PackPush {
  uint32_t count, kv_len, heads, d4;
  uint32_t k_off, k_stride, v_off, v_stride;
};

}  // namespace

void attention(vk::Recorder& rec, const AttentionShape& s, const AttentionOperand& q, const AttentionOperand& k,
               const AttentionOperand& v, const AttentionOperand& out, const AttentionOptions& opt) {
  if (s.head_dim < 4 || s.head_dim > 128 || s.head_dim % 4)
    fail("head_dim " + std::to_string(s.head_dim) + " is not a multiple of 4 in [4, 128]");
  if (s.batch < 0 || s.heads < 1 || s.q_len < 0 || s.kv_len < 0) fail("negative or zero size");
  if (s.batch == 0 || s.q_len == 0) return;
  if (s.kv_len == 0) fail("no keys (kv_len = 0): softmax over nothing is undefined");
  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  Blocking blk = blocking_for(caps, s.head_dim);
  if (opt.rows_per_invocation) {
    if (opt.rows_per_invocation > 16) fail("rows_per_invocation must be at most 16");
    blk.rows = opt.rows_per_invocation;
  }
  const int64_t rows_per_group = int64_t(kWorkgroupSize) * blk.rows;
  if (div_up(s.q_len, rows_per_group) > caps.max_workgroup_count[0] || s.heads > caps.max_workgroup_count[1] ||
      s.batch > caps.max_workgroup_count[2])
    fail("q_len/heads/batch exceed the dispatch grid");
  const int64_t width = s.heads * s.head_dim;
  Bound bq = bind_operand("q", q, s.batch, s.q_len, width, true, caps);
  Bound bk = bind_operand("k", k, s.batch, s.kv_len, width, true, caps);
  Bound bv = bind_operand("v", v, s.batch, s.kv_len, width, true, caps);
  Bound bo = bind_operand("out", out, s.batch, s.q_len, width, false, caps);

  if (opt.bias) {
    expect_dtype("attention", "bias", *opt.bias, DType::f32);
    expect_shape("attention", "bias", *opt.bias, {s.heads, s.q_len, s.kv_len});
    if (opt.bias->numel() > int64_t(UINT32_MAX)) fail("bias too large to index");
  }
  if (opt.key_mask) {
    expect_dtype("attention", "key_mask", *opt.key_mask, DType::f32);
    expect_shape("attention", "key_mask", *opt.key_mask, {s.batch, s.kv_len});
  }

  const uint32_t spec[] = {uint32_t(s.head_dim / 4), opt.bias ? 1u : 0u, opt.key_mask ? 1u : 0u, blk.rows, blk.keys};
  const vk::Pipeline& pipe = ctx.pipelines().get("nn/attention", spec);

  const uint32_t d4 = uint32_t(s.head_dim / 4), kv_len = uint32_t(s.kv_len);
  Push push{uint32_t(s.q_len), kv_len, uint32_t(s.heads), bq.off4, bq.stride4, bo.off4, bo.stride4,
            // k and v token-major: batch stride Lk rows, head stride D
            bk.off4, bk.stride4, kv_len * bk.stride4, d4, bv.off4, bv.stride4, kv_len * bv.stride4, d4,
            opt.scale, 0, 0};
  const VkFormat rgba = VK_FORMAT_R32G32B32A32_SFLOAT;
  vk::Binding k_binding(bk.view, rgba), v_binding(bv.view, rgba);

  if (opt.workspace) {
    // Repack K and V head-major [B, H, Lk, D] (K then V) and read them from there.
    const int64_t count = s.batch * s.heads * s.kv_len * int64_t(d4);  // vec4s per tensor
    expect_dtype("attention", "workspace", *opt.workspace, DType::f32);
    if (opt.workspace->numel() < attention_workspace_elements(s))
      fail("workspace " + opt.workspace->describe() + " is smaller than the " +
           std::to_string(attention_workspace_elements(s)) + " elements needed");
    if (2 * count > int64_t(UINT32_MAX)) fail("workspace too large to index");
    vk::BufferView ws = opt.workspace->buffer();
    ws.size = VkDeviceSize(2 * count) * 16;
    Bound bw = bind_operand("workspace", {*opt.workspace, 0, 4}, 1, 2 * count, 4, true, caps);  // as 2·count vec4 rows
    PackPush pp{uint32_t(count), kv_len, uint32_t(s.heads), d4, bk.off4, bk.stride4, bv.off4, bv.stride4};
    Grid g = grid_1d(count, 64);
    rec.dispatch(ctx.pipelines().get("nn/attention_pack"), {k_binding, v_binding, ws}, &pp, sizeof pp, g.x, g.y, 2,
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
    vk::BufferView v = t->buffer();
    VkDeviceSize shift = v.offset % kTexelOffsetAlign;
    if (shift % 4) fail(std::string(name) + " is not 4-byte aligned");
    if ((uint64_t(t->numel()) + shift / 4) > caps.max_texel_buffer_elements)
      fail(std::string(name) + " has more elements than this device's maxTexelBufferElements");
    vk::BufferView aligned{v.buffer, v.offset - shift, VkDeviceSize(t->numel()) * 4 + shift,
                           v.mapped ? v.mapped - shift : nullptr};
    shift_elems = uint32_t(shift / 4);
    return vk::Binding(aligned, VK_FORMAT_R32_SFLOAT);
  };
  vk::Binding bias_binding = scalar_texels(opt.bias, "bias", push.bias_off);
  vk::Binding mask_binding = scalar_texels(opt.key_mask, "key_mask", push.mask_off);
  rec.dispatch(pipe, {vk::Binding(bq.view, rgba), k_binding, v_binding, bo.view, bias_binding, mask_binding},
               &push, sizeof push, div_up(s.q_len, rows_per_group), uint32_t(s.heads), uint32_t(s.batch),
               "attention");
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
  return 2 * s.batch * s.heads * s.kv_len * s.head_dim;
}

bool attention_workspace_helps(const vk::DeviceCaps& caps, const AttentionShape& s) {
  // Measured: no change at H ≤ 2 or short sequences, +15% at H=8/L=1024, ×1.8 at H=48/L=2048.
  return caps.type == VK_PHYSICAL_DEVICE_TYPE_CPU && s.heads >= 4 && s.kv_len >= 512;
}

AttentionOperand fused_qkv_operand(const Tensor& qkv, int which, int64_t heads, int64_t head_dim) {
  if (which < 0 || which > 2) fail("fused_qkv_operand: which must be 0 (q), 1 (k) or 2 (v)");
  int64_t width = heads * head_dim;
  if (qkv.rank() < 1 || qkv.dim(-1) != 3 * width)
    fail("fused QKV tensor " + qkv.describe() + " does not end in 3·H·D = " + std::to_string(3 * width));
  return {qkv, which * width, 3 * width};
}

}  // namespace dvs::ops
