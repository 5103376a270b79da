// The GPU families of ops::attention (DeviceTuning::attention): `tiled` (shaders/nn/attention_flash.comp,
// shared-memory K/V tiles, fp32 FMA) and `coopmat` (shaders/nn/attention_flash_coopmat.comp, tensor cores).
// Internal to ops_attention.cpp: it validates the operands and asks plan() which kernel runs a call whose
// head_dim is a multiple of 4 (a padded head_dim arrives here on its padded copies).
//
// These kernels take whole calls only: no bias, no key mask, one dispatch within the limits in force. Every
// other call (T5's bias and mask, calls the texel path would split) runs on the texel kernel
// (shaders/nn/attention.comp) with its split paths, so every split keeps working on every device.
#pragma once
#include <cstdint>
#include <string>

#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_attention.hpp"

namespace dvs::ops {

// The push constants of every attention kernel (shaders/nn/attention.comp and the flash kernels, which leave the
// bias/mask fields unused; q's batch and head strides are the flash kernels' alone: attention.comp reads q
// token-major). Offsets and strides in vec4 units (groups of 4 elements); bias and mask offsets in elements.
struct AttentionPush {
  uint32_t q_len, kv_len, heads;
  uint32_t q_off, q_stride, o_off, o_stride;
  uint32_t k_off, k_stride, k_bstride, k_hstride;
  uint32_t v_off, v_stride, v_bstride, v_hstride;
  float scale;
  uint32_t bias_off, bias_hstride, bias_rstride, mask_off;
  uint32_t q_bstride, q_hstride;
};

}  // namespace dvs::ops

namespace dvs::ops::flash {

struct Plan {
  KernelFamily family = KernelFamily::texel;  // texel: the flash kernels do not take this call
  uint32_t block_q = 0, block_k = 0;          // query rows per workgroup, keys per shared tile
  bool twin = false;  // family tiled, kernel attention_flash_coopmat_twin.comp (DeviceTuning::attention_coopmat_twin)
  // Where the tuning asks for tensor cores and this call runs another kernel: why, and whether the reason is
  // the device's (kernel_census.hpp).
  std::string fallback;
  bool device_fallback = false;
};

// ops: q, k, v, out (already checked against the shape); strides: their row strides in elements.
Plan plan(const vk::DeviceCaps& caps, const AttentionShape& s, const AttentionOperand* const ops[4],
          const int64_t strides[4], const AttentionOptions& opt);

void record(vk::Recorder& rec, const AttentionShape& s, const AttentionOperand* const ops[4], const int64_t strides[4],
            const AttentionOptions& opt, const Plan& plan);

}  // namespace dvs::ops::flash
