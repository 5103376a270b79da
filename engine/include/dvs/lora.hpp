// A LoRA adapter as `--lora FILE[:SCALE]` names it (diffusers / PEFT safetensors layout; applied to the
// transformer by RunOptions::lora and lora_scale).
#pragma once
#include <filesystem>
#include <string>

#include "dvs/api.hpp"

namespace dvs {

struct LoraArgument {
  std::filesystem::path file;
  double scale = 1.0;
};

// "FILE" or "FILE:SCALE". A spec naming an existing file is that file (paths may hold ':'); otherwise what
// follows the last ':' must be a finite number. Throws dvs::UsageError when it is not.
DVS_API LoraArgument parse_lora_argument(const std::string& spec);

}  // namespace dvs
