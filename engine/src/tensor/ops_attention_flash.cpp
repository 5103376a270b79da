#include "tensor/ops_attention_flash.hpp"

#include <algorithm>
#include <span>
#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/coopmat_layout.hpp"
#include "tensor/kernel_census.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs::ops::flash {
namespace {

// Elements an operand's binding covers from its tensor's start.
int64_t span_elements(const AttentionShape& s, const AttentionOperand& a, int64_t len, int64_t stride) {
  return (s.batch * len - 1) * stride + a.column_offset + s.heads * s.head_dim;
}

// Whether every operand fits one storage binding (from its aligned-down start) and vec4 indices fit 32 bits.
bool fits_bindings(const vk::DeviceCaps& caps, const AttentionShape& s, const AttentionOperand* const ops[4],
                   const int64_t strides[4]) {
  const int64_t lens[4] = {s.q_len, s.kv_len, s.kv_len, s.q_len};
  const uint64_t align = binding_alignment(caps), cap = binding_capacity(caps, 0);
  for (int i = 0; i < 4; ++i) {
    const uint64_t elem = dtype_size(ops[i]->t.dtype());  // 4, or 2 for an f16 k, v or out
    const uint64_t bytes = uint64_t(span_elements(s, *ops[i], lens[i], strides[i])) * elem +
                           ops[i]->t.buffer().offset % align;
    if (bytes > cap || bytes / (4 * elem) > UINT32_MAX) return false;
  }
  return true;
}

bool fits_grid(const vk::DeviceCaps& caps, const AttentionShape& s, uint32_t block_q) {
  return div_up(s.q_len, block_q) <= caps.max_workgroup_count[0] && s.heads <= caps.max_workgroup_count[1] &&
         s.batch <= caps.max_workgroup_count[2];
}

}  // namespace

Plan plan(const vk::DeviceCaps& caps, const AttentionShape& s, const AttentionOperand* const ops[4],
          const int64_t strides[4], const AttentionOptions& opt) {
  const DeviceTuning& t = device_tuning(caps);
  const bool asked_coopmat = t.attention == KernelFamily::coopmat;
  // Why this call does not run on tensor cores where they were asked for (device: the device's reason; the
  // tuning's own, attention_unfit, when the device holds no layout at all).
  auto fallback = [&](Plan p, std::string why, bool device) {
    if (!asked_coopmat && t.attention_unfit.empty()) return p;
    p.fallback = why.empty() ? t.attention_unfit : why;
    p.device_fallback = why.empty() || device;
    return p;
  };
  if (t.attention == KernelFamily::texel) return {};
  // T5's relative bias and key mask run on the texel kernel (short sequences; not worth a third variant).
  if (opt.bias || opt.key_mask) return fallback({}, "a relative bias or key mask (the texel kernel takes those)", false);
  if (!fits_bindings(caps, s, ops, strides))  // the texel kernel's split paths take it
    return fallback({}, "an operand over one binding (the texel kernel's split paths take it)",
                    !caps.forced_limits.any());
  const int64_t D = s.head_dim;

  // Tensor cores: the tuning's layout, where it takes this head_dim within the device's limits. Else the tiled kernel.
  std::string why_not;
  bool device_reason = false;
  if (asked_coopmat) {
    const CoopmatAttention a = attention_coopmat_layout(t);
    why_not = attention_coopmat_head_dim_unfit(a, D);
    if (why_not.empty()) {
      why_not = attention_coopmat_unfit(caps, a, D, attention_coopmat_kernel(caps, t));
      device_reason = true;
    }
    if (why_not.empty() && !fits_grid(caps, s, uint32_t(a.rows()))) {
      why_not = "more query blocks than maxComputeWorkGroupCount";
      device_reason = !caps.forced_limits.any();
    }
    if (why_not.empty()) return {KernelFamily::coopmat, uint32_t(a.rows()), uint32_t(a.block_k)};
  }

  // Tests on devices without tensor cores: the coopmat kernel's twin, where it fits.
  if (t.attention_coopmat_twin && caps.float16_arithmetic) {
    const CoopmatAttention a = attention_coopmat_layout(t);
    if (attention_coopmat_unfit(caps, a, D, AttentionKernel::twin).empty() && fits_grid(caps, s, uint32_t(a.rows())))
      return {KernelFamily::tiled, uint32_t(a.rows()), uint32_t(a.block_k), true};
  }

  // Tiled: one query row per invocation; the K and V tiles (fp32) within shared memory, in steps of 4 keys.
  const uint32_t bq = std::min<uint32_t>(uint32_t(t.attention_block_q), caps.max_workgroup_invocations);
  const int64_t fit = int64_t(caps.max_compute_shared_memory) / (2 * D * 4);
  const uint32_t bk = uint32_t(std::min<int64_t>(t.attention_block_k, fit) / 4 * 4);
  if (bk < 4 || bq < 1 || !fits_grid(caps, s, bq))
    return fallback({}, why_not.empty() ? "" : why_not + "; neither does the tiled kernel", device_reason);
  return fallback({KernelFamily::tiled, bq, bk}, why_not, device_reason);
}

void record(vk::Recorder& rec, const AttentionShape& s, const AttentionOperand* const ops[4], const int64_t strides[4],
            const AttentionOptions& opt, const Plan& plan) {
  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  const int64_t lens[4] = {s.q_len, s.kv_len, s.kv_len, s.q_len};
  const uint64_t align = binding_alignment(caps);
  const uint32_t d4 = uint32_t(s.head_dim / 4);
  vk::BufferView views[4];
  // Per operand, in groups of 4 elements: the offset, and the strides between rows, heads and batch elements.
  // Token-major: rows strides[i] apart, heads D, batch elements L rows; head-major [B, H, L, D]: rows D apart, heads
  // L·D, batch elements H·L·D.
  uint32_t off4[4], row4[4], head4[4], batch4[4];
  for (int i = 0; i < 4; ++i) {
    const AttentionOperand& a = *ops[i];
    const uint32_t elem = uint32_t(dtype_size(a.t.dtype()));  // 4, or 2 for an f16 operand
    const uint64_t bytes = uint64_t(span_elements(s, a, lens[i], strides[i])) * elem;
    uint32_t base = 0;  // group of 4 elements at the view's start, modulo 2^32 (0 or "minus the shift")
    views[i] = aligned_view(a.t.buffer(), 0, bytes, align, 4 * elem, base);
    off4[i] = uint32_t(a.column_offset / 4) - base;
    row4[i] = a.head_major ? d4 : uint32_t(strides[i] / 4);
    head4[i] = a.head_major ? uint32_t(lens[i]) * d4 : d4;
    batch4[i] = a.head_major ? uint32_t(s.heads) * head4[i] : uint32_t(lens[i]) * row4[i];
  }
  AttentionPush push{uint32_t(s.q_len), uint32_t(s.kv_len), uint32_t(s.heads), off4[0], row4[0], off4[3], row4[3],
                     off4[1], row4[1], batch4[1], head4[1], off4[2], row4[2], batch4[2], head4[2], opt.scale, 0, 0,
                     0, 0, batch4[0], head4[0]};
  // O_F16, KV_F16, Q_F16: those operands' offsets and strides in groups of 4 halves.
  const bool out_f16 = ops[3]->t.dtype() == DType::f16, kv_f16 = ops[1]->t.dtype() == DType::f16;
  const bool q_f16 = ops[0]->t.dtype() == DType::f16;
  const bool coop = plan.family == KernelFamily::coopmat;
  const DeviceTuning& tune = device_tuning(caps);
  // The family's kernel (meaningful where coop or plan.twin).
  const AttentionKernel kernel = plan.twin ? AttentionKernel::twin : attention_coopmat_kernel(caps, tune);
  const char* name = plan.twin ? "attention_flash_coopmat_twin"
                     : !coop   ? "attention_flash"
                     : kernel == AttentionKernel::coopmat2 ? "attention_flash_coopmat2"
                                                           : "attention_flash_coopmat";
  const vk::Pipeline* pipe_ptr = nullptr;
  if (coop || plan.twin) {  // the layout plan() checked, with this head_dim
    const CoopmatAttention a = attention_coopmat_layout(tune);
    const std::vector<uint32_t> spec = attention_coopmat_spec(a, s.head_dim, out_f16, kv_f16, q_f16);
    pipe_ptr = &coopmat_pipeline(ctx, std::string("nn/") + name, spec, coop ? uint32_t(a.lanes) : 0u,
                                 attention_coopmat_unfit(caps, a, s.head_dim, kernel));
  } else {
    const uint32_t spec_tiled[] = {plan.block_q, d4, plan.block_k, out_f16 ? 1u : 0u, kv_f16 ? 1u : 0u, q_f16 ? 1u : 0u};
    pipe_ptr = &ctx.pipelines().get(std::string("nn/") + name, spec_tiled);
  }
  const vk::Pipeline& pipe = *pipe_ptr;
  note_kernel(ctx, "attention", plan.family, pipe.name, {plan.fallback, plan.device_fallback});
  rec.dispatch(pipe, {views[0], views[1], views[2], views[3]}, &push, sizeof push, div_up(s.q_len, plan.block_q),
               uint32_t(s.heads), uint32_t(s.batch), name);
}

}  // namespace dvs::ops::flash
