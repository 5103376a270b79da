// Copies of the conformance pack's model with one thing changed, for tests of what a run does with bad models:
// a weight set to NaN, a weight removed, a config value changed.
#pragma once
#include <filesystem>
#include <functional>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "spec/model_folder.hpp"
#include "io/safetensors_writer.hpp"
#include "support/files.hpp"

namespace dvs::test {

// A full copy of `model` at `to`.
inline std::filesystem::path copy_model(const std::filesystem::path& model, const std::filesystem::path& to) {
  std::filesystem::copy(model, to, std::filesystem::copy_options::recursive);
  return to;
}

// Rewrites `component`'s single safetensors file through `edit` (which may change, add or drop tensors).
inline void edit_weights(const std::filesystem::path& model, const std::string& component,
                         const std::function<void(std::vector<std::pair<std::string, HostTensor>>&)>& edit) {
  std::filesystem::path file;
  std::vector<std::pair<std::string, HostTensor>> tensors;
  {
    const WeightSet ws = WeightSet::open_dir(model / component);
    file = ws.source();
    for (const auto& [name, ref] : ws.entries()) tensors.push_back({name, ws.load(name)});
  }
  edit(tensors);
  std::filesystem::remove(file);
  write_safetensors(file, tensors);
}

// Sets element `index` of tensor `name` (f32 storage) of `component` to NaN.
inline void plant_nan(const std::filesystem::path& model, const std::string& component, const std::string& name, int64_t index = 0) {
  edit_weights(model, component, [&](auto& tensors) {
    for (auto& [n, t] : tensors)
      if (n == name) t.template as<float>()[index] = std::numeric_limits<float>::quiet_NaN();
  });
}

// Changes `component`/config.json through `edit`.
inline void edit_config(const std::filesystem::path& model, const std::string& component,
                        const std::function<void(nlohmann::json&)>& edit) {
  const auto path = model / component / "config.json";
  nlohmann::json j = nlohmann::json::parse(read_text(path));
  edit(j);
  write_text(path, j.dump(2));
}

}  // namespace dvs::test
