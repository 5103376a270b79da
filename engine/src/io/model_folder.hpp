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

#include "io/safetensors.hpp"

namespace dvs {

// Reads and parses a JSON file; dvs::Error names the file (and `what_to_do` when it is missing).
nlohmann::json read_json_file(const std::filesystem::path& path, std::string_view what_to_do = {});

// Where one weight lives: the (mapped) file that holds it and its header entry.
struct WeightRef {
  const SafetensorsFile* file = nullptr;
  const TensorInfo* info = nullptr;
};

// All weights of one component, merged across shards. Owns the mapped files.
class WeightSet {
 public:
  // Finds the weights in a component folder: `model.safetensors` / `diffusion_pytorch_model.safetensors`,
  // else their `.index.json` shard index, else the only *.safetensors or *.safetensors.index.json present.
  static WeightSet open_dir(const std::filesystem::path& dir);
  // One file: a .safetensors, or a *.safetensors.index.json naming shards next to it.
  static WeightSet open_file(const std::filesystem::path& file);
  // Whether `dir` holds any *.safetensors weights at all (tokenizer/scheduler folders do not).
  static bool dir_has_weights(const std::filesystem::path& dir);

  const std::filesystem::path& source() const { return source_; }  // the .safetensors or the index file
  bool sharded() const { return sharded_; }
  const std::vector<std::unique_ptr<SafetensorsFile>>& files() const { return files_; }
  // Name -> location, sorted by name.
  const std::map<std::string, WeightRef, std::less<>>& entries() const { return entries_; }
  size_t size() const { return entries_.size(); }
  const WeightRef* find(std::string_view name) const;
  std::span<const uint8_t> bytes(std::string_view name) const;  // throws if absent
  HostTensor load(std::string_view name) const;                 // throws if absent / not an engine dtype
  uint64_t total_bytes() const;
  // Non-fatal findings (tensors in a shard that the index does not list, total_size mismatch).
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  void add_file_tensors(const SafetensorsFile& f);
  static WeightSet open_index(const std::filesystem::path& index);

  std::filesystem::path source_;
  bool sharded_ = false;
  std::vector<std::unique_ptr<SafetensorsFile>> files_;
  std::map<std::string, WeightRef, std::less<>> entries_;
  std::vector<std::string> warnings_;
};

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
