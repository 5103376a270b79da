// LoRA adapters in the diffusers / PEFT safetensors layout, applied unmerged as diffusers does after
// load_lora_weights: y = W·x + b + scale·B·(A·x), with A = "<module>.lora_A.weight" [rank, in] and
// B = "<module>.lora_B.weight" [out, rank]; scale = user scale · (alpha / rank) when the file holds
// "<module>.alpha", else the user scale (PEFT's default lora_alpha = rank). Module names are taken after an
// optional "transformer." prefix (diffusers' saved layout), e.g. "transformer_blocks.3.attn1.to_q".
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>

#include "tensor/tensor.hpp"

namespace dvs::vk {
class Context;
}

namespace dvs::models {

struct LoraAdapter {
  Tensor down;  // A [rank, in], stored dtype (f32 / f16 / bf16)
  Tensor up;    // scale·B [out, rank], f32
  int64_t rank = 0;
};

// Module name -> adapter. Throws dvs::Error naming the file and tensor on a malformed entry.
std::map<std::string, LoraAdapter> load_lora(vk::Context& ctx, const std::filesystem::path& file, float scale = 1.0f,
                                             const std::string& prefix = "transformer.");

}  // namespace dvs::models
