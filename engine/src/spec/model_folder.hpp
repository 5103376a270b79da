// A Hugging Face pipeline folder laid out like THUDM/CogVideoX-5b-I2V: model_index.json names the
// components; each component folder holds config.json and its weights, either one *.safetensors or shards
// listed by a *.safetensors.index.json. Read as-is: no conversion step.
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "io/json_file.hpp"
#include "io/weight_set.hpp"

namespace dvs {

// One entry of model_index.json.
struct ComponentEntry {
  std::string name;        // "transformer"
  std::string library;     // "diffusers"
  std::string class_name;  // "CogVideoXTransformer3DModel"
};

// A component folder opened: its config and, when it has any, its weights.
struct Component {
  ComponentEntry entry;
  std::filesystem::path dir;
  std::filesystem::path config_path;
  nlohmann::json config;
  std::optional<WeightSet> weights;
};

class ModelFolder {
 public:
  // Reads <root>/model_index.json. Throws dvs::Error if it is missing or malformed.
  static ModelFolder open(const std::filesystem::path& root);

  const std::filesystem::path& root() const { return root_; }
  const std::string& pipeline_class() const { return pipeline_class_; }  // "_class_name"
  const nlohmann::json& index() const { return index_; }
  // Components in model_index.json, sorted by name; entries whose value is [null, null] are skipped.
  const std::vector<ComponentEntry>& components() const { return components_; }
  const ComponentEntry* find(std::string_view name) const;

  // The component's config file: config.json, or scheduler_config.json / tokenizer_config.json when that
  // is what the folder holds.
  std::filesystem::path config_path(std::string_view name) const;
  nlohmann::json config(std::string_view name) const;
  // The component's weights; throws if the folder has none.
  WeightSet weights(std::string_view name) const;
  // Config plus weights (when present) in one go.
  Component load(std::string_view name) const;

 private:
  const ComponentEntry& require(std::string_view name) const;

  std::filesystem::path root_;
  nlohmann::json index_;
  std::string pipeline_class_;
  std::vector<ComponentEntry> components_;
};

// The model class named by a component's own config: diffusers "_class_name", or transformers
// "architectures"[0]. Empty if neither is present.
std::string config_class_name(const nlohmann::json& config);

}  // namespace dvs
