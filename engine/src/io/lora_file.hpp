// LoRA adapters in the diffusers / PEFT safetensors layout, read on the host: A = "<module>.lora_A.weight"
// [rank, in], B = "<module>.lora_B.weight" [out, rank], optional "<module>.alpha". The effective scale is the
// user scale · (alpha / rank) when the file holds alpha, else the user scale (PEFT's default lora_alpha =
// rank). Module names are taken after an optional prefix ("transformer." in diffusers' saved layout), e.g.
// "transformer_blocks.3.attn1.to_q". Used unmerged by models/cogvideox/lora.hpp and merged by dvs-weights merge-lora.
#pragma once
#include <filesystem>
#include <map>
#include <string>

#include "io/host_tensor.hpp"

namespace dvs {

struct LoraFileAdapter {
  HostTensor a, b;     // A [rank, in], B [out, rank], stored dtype
  double scale = 1.0;  // user scale · (alpha / rank), or the user scale
  int64_t rank() const { return a.shape[0]; }
};

// Module name -> adapter. Throws dvs::Error naming the file and tensor on a malformed entry or an empty file.
std::map<std::string, LoraFileAdapter> read_lora_file(const std::filesystem::path& file, double user_scale,
                                                      const std::string& prefix = "transformer.");

// "FILE" or "FILE:SCALE", as --lora takes it. A spec naming an existing file is that file (paths may hold ':');
// otherwise what follows the last ':' must be a number. Throws dvs::Error when it is not.
struct LoraSpec {
  std::filesystem::path file;
  double scale = 1.0;
};
LoraSpec parse_lora_spec(const std::string& spec);

}  // namespace dvs
