// LoRA adapters applied unmerged as diffusers does after load_lora_weights: y = W·x + b + scale·B·(A·x). The
// file layout, the scale rule and the module names are in io/lora_file.hpp.
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
