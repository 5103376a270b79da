// A Hugging Face pipeline folder: model_index.json and its component folders.
#include "spec/model_folder.hpp"

#include "dvs/error.hpp"

namespace dvs {
namespace fs = std::filesystem;
using nlohmann::json;

std::string config_class_name(const json& config) {
  if (!config.is_object()) return {};
  if (auto it = config.find("_class_name"); it != config.end() && it->is_string()) return it->get<std::string>();
  if (auto it = config.find("architectures"); it != config.end() && it->is_array() && !it->empty() &&
                                               (*it)[0].is_string())
    return (*it)[0].get<std::string>();
  return {};
}

ModelFolder ModelFolder::open(const fs::path& root) {
  std::error_code ec;
  if (!fs::is_directory(root, ec)) throw Error(root.string() + ": not a folder (expected a Hugging Face pipeline folder)");
  ModelFolder m;
  m.root_ = root;
  const fs::path idx = root / "model_index.json";
  m.index_ = read_json_file(idx, "point at a Hugging Face pipeline folder such as a download of THUDM/CogVideoX-5b-I2V");
  if (!m.index_.is_object()) throw Error(idx.string() + ": not a JSON object");
  if (auto it = m.index_.find("_class_name"); it != m.index_.end() && it->is_string())
    m.pipeline_class_ = it->get<std::string>();
  for (const auto& [key, v] : m.index_.items()) {
    if (!key.empty() && key[0] == '_') continue;  // _class_name, _diffusers_version, _name_or_path ...
    if (!v.is_array()) continue;                  // plain settings such as "requires_safety_checker": false
    if (v.size() != 2) throw Error(idx.string() + ": component '" + key + "' must be [library, class]");
    if (v[0].is_null() && v[1].is_null()) continue;  // an optional component that is not provided
    if (!v[0].is_string() || !v[1].is_string())
      throw Error(idx.string() + ": component '" + key + "' must be [library, class] strings");
    if (key.find('/') != std::string::npos || key == "." || key == "..")
      throw Error(idx.string() + ": component name '" + key + "' is not a folder name");
    m.components_.push_back({key, v[0].get<std::string>(), v[1].get<std::string>()});
  }
  return m;
}

const ComponentEntry* ModelFolder::find(std::string_view name) const {
  for (const auto& c : components_)
    if (c.name == name) return &c;
  return nullptr;
}

const ComponentEntry& ModelFolder::require(std::string_view name) const {
  const ComponentEntry* c = find(name);
  if (!c) throw Error((root_ / "model_index.json").string() + ": no component '" + std::string(name) + "'");
  std::error_code ec;
  if (!fs::is_directory(root_ / c->name, ec))
    throw Error((root_ / c->name).string() + ": component folder listed in model_index.json is missing; "
                "the download is incomplete");
  return *c;
}

fs::path ModelFolder::config_path(std::string_view name) const {
  const fs::path dir = root_ / require(name).name;
  std::error_code ec;
  for (const char* f : {"config.json", "scheduler_config.json", "tokenizer_config.json", "preprocessor_config.json"})
    if (fs::is_regular_file(dir / f, ec)) return dir / f;
  return dir / "config.json";
}

json ModelFolder::config(std::string_view name) const {
  return read_json_file(config_path(name), "every component folder needs its config; re-download it");
}

WeightSet ModelFolder::weights(std::string_view name) const { return WeightSet::open_dir(root_ / require(name).name); }

Component ModelFolder::load(std::string_view name) const {
  Component c;
  c.entry = require(name);
  c.dir = root_ / c.entry.name;
  c.config_path = config_path(name);
  c.config = config(name);
  if (WeightSet::dir_has_weights(c.dir)) c.weights = WeightSet::open_dir(c.dir);
  return c;
}

}  // namespace dvs
