// `dvs-weights merge-lora`: a complete model folder whose transformer has a LoRA merged into its weights,
// W' = W + scale·(alpha/rank)·B·A (models/cogvideox/lora.hpp gives the file layout and the scale rule), stored in W's
// dtype and sharded like the input. Host only: no device.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

namespace dvs::weights_tools {

struct MergeLoraOptions {
  std::filesystem::path model, lora, out;
  double scale = 1.0;                    // the user scale (diffusers' lora_scale)
  std::string prefix = "transformer.";   // module-name prefix in the LoRA file, stripped when present
};

struct MergeLoraReport {
  int merged_modules = 0;
  int64_t rank = 0;  // largest rank seen
};

// Writes the whole folder under a temporary name next to `out` and renames it at the end; `out` must not exist
// or be an empty folder. Throws dvs::Error naming the file, tensor or option at fault.
MergeLoraReport merge_lora_folder(const MergeLoraOptions& options);

// The command: parses argv (after "merge-lora"), returns the exit status (0 ok, 1 error, 2 usage).
int merge_lora_command(const std::vector<std::string>& args);

}  // namespace dvs::weights_tools
