// Typed reads of a model's config.json values, each error naming the file and the key ("<origin>: 'key' ...").
//
// Two reading rules live here because two kinds of reader need them:
//  - the schema readers (model_schema.cpp) are strict: a null value is an error, integral floats (4.0, as Python
//    configs sometimes hold) are accepted, and every size is bounded by kMaxConfigDim;
//  - the model configs (cogvideox_config, t5_config) follow the libraries' constructors: a missing or null key
//    takes the constructor's default, anything else must be an integer at or above a minimum.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace dvs {

constexpr int64_t kMaxConfigDim = int64_t(1) << 31;  // any larger "size" in a config is a typo or an attack

class ConfigValues {
 public:
  // `config` must outlive this reader; `origin` (the config's path) starts every message.
  ConfigValues(const nlohmann::json& config, std::string_view origin) : j_(config), origin_(origin) {}

  const std::string& origin() const { return origin_; }
  // Throws "<origin>: config is not a JSON object" unless it is one.
  void require_object() const;
  [[noreturn]] void fail(const std::string& key, const std::string& what) const;

  // ---- strict (schemas) ----
  // Integer in [lo, kMaxConfigDim]; missing -> def; null -> error.
  int64_t integer(const std::string& key, int64_t def, int64_t lo = 0) const;
  // Missing or null -> nullopt (for keys where null means "feature off").
  std::optional<int64_t> opt_integer(const std::string& key, int64_t lo = 0) const;
  bool boolean(const std::string& key, bool def) const;
  std::string string(const std::string& key, const std::string& def) const;
  std::vector<int64_t> integers(const std::string& key, std::vector<int64_t> def, int64_t lo) const;
  std::vector<std::string> strings(const std::string& key, std::vector<std::string> def) const;

  // ---- constructor defaults (model configs) ----
  // Missing or null -> def; otherwise a JSON integer in [min, kMaxConfigDim] ("'key' must be an integer in min..max").
  int64_t integer_or_default(const char* key, int64_t def, int64_t min) const;
  // Missing or null -> def; otherwise true or false ("'key' must be true or false").
  bool boolean_or_default(const char* key, bool def) const;
  // The number when the key holds one, else `def` (the libraries ignore other values here too).
  float number_or_default(const char* key, float def) const;

 private:
  const nlohmann::json& j_;
  std::string origin_;
};

}  // namespace dvs
