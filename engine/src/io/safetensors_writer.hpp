// Writes a .safetensors file (8-byte little-endian header length, JSON header padded with spaces to a
// multiple of 8, then the tensors back to back) to a temporary name and renames it when complete.
#pragma once
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "io/host_tensor.hpp"

namespace dvs {

void write_safetensors(const std::filesystem::path& path, const std::vector<std::pair<std::string, HostTensor>>& tensors,
                       const std::map<std::string, std::string>& metadata = {{"format", "pt"}});

}  // namespace dvs
