#include "tensor/ops_attention_flash.hpp"

#include <algorithm>
#include <span>
#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs::ops::flash {
namespace {

// attention_flash_coopmat.comp: 4 subgroups of 32 lanes, 16 query rows each, 16x16x16 fragments.
constexpr uint32_t kCoopmatRows = 64, kCoopmatFrag = 16;

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
    const uint64_t bytes = uint64_t(span_elements(s, *ops[i], lens[i], strides[i])) * 4 +
                           ops[i]->t.buffer().offset % align;
    if (bytes > cap || bytes / 16 > UINT32_MAX) return false;
  }
  return true;
}

bool fits_grid(const vk::DeviceCaps& caps, const AttentionShape& s, uint32_t block_q) {
  return div_up(s.q_len, block_q) <= caps.max_workgroup_count[0] && s.heads <= caps.max_workgroup_count[1] &&
         s.batch <= caps.max_workgroup_count[2];
}

}  // namespace

uint64_t coopmat_shared_bytes(int64_t D, int64_t bk) {
  // K and V tiles (fp16), per subgroup: scores / P·V tile (fp32, 16 x max(BK, D)), probabilities (fp16, 16 x BK).
  return uint64_t(2 * bk * D * 2 + 4 * 16 * std::max(bk, D) * 4 + 4 * 16 * bk * 2);
}

uint64_t coopmat_twin_shared_bytes(int64_t D, int64_t bk) { return coopmat_shared_bytes(D, bk) + 4 * 16 * D * 2 + 128 * 4; }

Plan plan(const vk::DeviceCaps& caps, const AttentionShape& s, const AttentionOperand* const ops[4],
          const int64_t strides[4], const AttentionOptions& opt) {
  const DeviceTuning& t = device_tuning(caps);
  if (t.attention == KernelFamily::texel) return {};
  // T5's relative bias and key mask run on the texel kernel (short sequences; not worth a third variant).
  if (opt.bias || opt.key_mask) return {};
  if (!fits_bindings(caps, s, ops, strides)) return {};  // the texel kernel's split paths take it
  const int64_t D = s.head_dim;

  // Tensor cores: head_dim a multiple of 16 up to the key tile (the P·V tile reuses the scores' shared
  // memory), the 16x16x16 shape, everything within the device's shared memory. Else the tiled kernel.
  if (t.attention == KernelFamily::coopmat && t.coopmat.m == kCoopmatFrag && t.coopmat.n == kCoopmatFrag &&
      t.coopmat.k == kCoopmatFrag && caps.float16_arithmetic && caps.subgroup_shuffle && caps.vulkan_memory_model &&
      D % 16 == 0) {
    const uint32_t bk = uint32_t(std::max(16, t.attention_block_k / 16 * 16));
    if (D <= int64_t(bk) && coopmat_shared_bytes(D, bk) <= caps.max_compute_shared_memory &&
        caps.max_workgroup_invocations >= 128 && fits_grid(caps, s, kCoopmatRows))
      return {KernelFamily::coopmat, kCoopmatRows, bk};
  }

  // Tests on devices without tensor cores: the coopmat kernel's twin, where it fits.
  if (t.attention_coopmat_twin && caps.float16_arithmetic && D % 16 == 0) {
    const uint32_t bk = uint32_t(std::max(16, t.attention_block_k / 16 * 16));
    if (D <= int64_t(bk) && coopmat_twin_shared_bytes(D, bk) <= caps.max_compute_shared_memory &&
        caps.max_workgroup_invocations >= 128 && fits_grid(caps, s, kCoopmatRows))
      return {KernelFamily::tiled, kCoopmatRows, bk, true};
  }

  // Tiled: one query row per invocation; the K and V tiles (fp32) within shared memory, in steps of 4 keys.
  const uint32_t bq = std::min<uint32_t>(uint32_t(t.attention_block_q), caps.max_workgroup_invocations);
  const int64_t fit = int64_t(caps.max_compute_shared_memory) / (2 * D * 4);
  const uint32_t bk = uint32_t(std::min<int64_t>(t.attention_block_k, fit) / 4 * 4);
  if (bk < 4 || bq < 1 || !fits_grid(caps, s, bq)) return {};
  return {KernelFamily::tiled, bq, bk};
}

void record(vk::Recorder& rec, const AttentionShape& s, const AttentionOperand* const ops[4], const int64_t strides[4],
            const AttentionOptions& opt, const Plan& plan) {
  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  const int64_t lens[4] = {s.q_len, s.kv_len, s.kv_len, s.q_len};
  const uint64_t align = binding_alignment(caps);
  vk::BufferView views[4];
  uint32_t off4[4], stride4[4];
  for (int i = 0; i < 4; ++i) {
    const AttentionOperand& a = *ops[i];
    const uint64_t bytes = uint64_t(span_elements(s, a, lens[i], strides[i])) * 4;
    uint32_t base = 0;  // vec4 of the tensor at the view's start, modulo 2^32 (0 or "minus the shift")
    views[i] = aligned_view(a.t.buffer(), 0, bytes, align, 16, base);
    off4[i] = uint32_t(a.column_offset / 4) - base;
    stride4[i] = uint32_t(strides[i] / 4);
  }
  const uint32_t d4 = uint32_t(s.head_dim / 4), kv_len = uint32_t(s.kv_len);
  // k and v token-major: batch stride Lk rows, head stride D (the head-major workspace pays on CPUs only).
  AttentionPush push{uint32_t(s.q_len), kv_len,   uint32_t(s.heads), off4[0], stride4[0], off4[3], stride4[3],
            off4[1],           stride4[1], kv_len * stride4[1], d4, off4[2],    stride4[2], kv_len * stride4[2],
            d4,                opt.scale, 0,                 0,  0,       0};
  const bool coop = plan.family == KernelFamily::coopmat;
  const uint32_t spec_tiled[] = {plan.block_q, d4, plan.block_k};
  const uint32_t spec_coop[] = {uint32_t(s.head_dim), plan.block_k};
  const char* name = coop ? "attention_flash_coopmat" : plan.twin ? "attention_flash_coopmat_twin" : "attention_flash";
  const vk::Pipeline& pipe = ctx.pipelines().get(std::string("nn/") + name, coop || plan.twin
                                                                              ? std::span<const uint32_t>(spec_coop)
                                                                              : std::span<const uint32_t>(spec_tiled));
  rec.dispatch(pipe, {views[0], views[1], views[2], views[3]}, &push, sizeof push, div_up(s.q_len, plan.block_q),
               uint32_t(s.heads), uint32_t(s.batch), name);
}

}  // namespace dvs::ops::flash
