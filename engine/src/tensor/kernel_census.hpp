// The kernel census of the GEMM-shaped ops (linear, attention, convolution): each call notes the family and
// shader it dispatched and, when that is not the family the tuning asked for, why (vk::Context::note_kernel).
// A fallback is the device's when a limit or property of the device decided it (the tuning's *_unfit, shared
// memory, the limits in force), the call's when its options or sizes did (the same on every device: T5's fp32
// operands and relative bias, a head_dim the tensor-core kernel does not take). The tensor-core pass
// (tests/run_coopmat_pass.sh) fails every test whose calls fell back for a reason of the device.
#pragma once
#include <string>

#include "tensor/kernel_tuning.hpp"
#include "vk/context.hpp"

namespace dvs::ops {

struct KernelFallback {
  std::string why;      // "" when the call ran the family asked for
  bool device = false;  // the device's reason (else the call's)
};

inline void note_kernel(vk::Context& ctx, const char* op, KernelFamily ran, const std::string& shader,
                        const KernelFallback& fallback = {}) {
  ctx.note_kernel({op, kernel_family_name(ran), shader, fallback.why, fallback.device && !fallback.why.empty()});
}

}  // namespace dvs::ops
