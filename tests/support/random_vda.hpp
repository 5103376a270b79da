// A tiny Video-Depth-Anything checkpoint for tests: the conformance pack's architecture with seeded random weights
// (models/random/vda_random), written as a .safetensors with the pack's config.json beside it.
#pragma once
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "io/safetensors_writer.hpp"
#include "models/random/vda_random.hpp"
#include "spec/vda_config.hpp"
#include "support/vda_pack.hpp"

namespace dvs::test {

// `poison` names a tensor filled with NaN, `fill` tensors filled with a value.
inline std::filesystem::path random_vda(const std::filesystem::path& dir, const std::string& poison = "",
                                        const std::map<std::string, float>& fill = {}) {
  std::filesystem::create_directories(dir);
  const VdaConfig cfg = vda_config_from_json(vda_model_config(), "pack config");
  auto tensors = vda_random_checkpoint(cfg, 11);
  for (auto& [name, t] : tensors) {
    if (name == poison) t = HostTensor::from_f32(t.shape, std::vector<float>(size_t(t.numel()), std::nanf("")));
    if (fill.count(name)) t = HostTensor::from_f32(t.shape, std::vector<float>(size_t(t.numel()), fill.at(name)));
  }
  const auto file = dir / "vda_random.safetensors";
  write_safetensors(file, tensors);
  std::filesystem::copy_file(vda_golden_path() / "model" / "config.json", dir / "config.json");
  return file;
}

}  // namespace dvs::test
