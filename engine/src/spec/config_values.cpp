#include "spec/config_values.hpp"

#include "dvs/error.hpp"

namespace dvs {

void ConfigValues::require_object() const {
  if (!j_.is_object()) throw Error(origin_ + ": config is not a JSON object");
}

void ConfigValues::fail(const std::string& key, const std::string& what) const {
  throw Error(origin_ + ": '" + key + "' " + what);
}

int64_t ConfigValues::integer(const std::string& key, int64_t def, int64_t lo) const {
  const auto v = opt_integer(key, lo);
  if (!v && j_.contains(key)) fail(key, "must be an integer, got null");
  return v.value_or(def);
}

std::optional<int64_t> ConfigValues::opt_integer(const std::string& key, int64_t lo) const {
  const auto it = j_.find(key);
  if (it == j_.end() || it->is_null()) return std::nullopt;
  int64_t v;
  if (it->is_number_integer()) {
    if (it->is_number_unsigned() && it->get<uint64_t>() > uint64_t(kMaxConfigDim)) fail(key, "is out of range: " + it->dump());
    v = it->get<int64_t>();
  } else if (it->is_number_float() && it->get<double>() == double(int64_t(it->get<double>())) &&
             it->get<double>() >= -double(kMaxConfigDim) && it->get<double>() <= double(kMaxConfigDim)) {
    v = int64_t(it->get<double>());
  } else {
    fail(key, "must be an integer, got " + it->dump());
  }
  if (v < lo || v > kMaxConfigDim)
    fail(key, "is out of range (" + std::to_string(lo) + ".." + std::to_string(kMaxConfigDim) + "): " + it->dump());
  return v;
}

bool ConfigValues::boolean(const std::string& key, bool def) const {
  const auto it = j_.find(key);
  if (it == j_.end()) return def;
  if (!it->is_boolean()) fail(key, "must be true or false, got " + it->dump());
  return it->get<bool>();
}

std::string ConfigValues::string(const std::string& key, const std::string& def) const {
  const auto it = j_.find(key);
  if (it == j_.end()) return def;
  if (!it->is_string()) fail(key, "must be a string, got " + it->dump());
  return it->get<std::string>();
}

std::vector<int64_t> ConfigValues::integers(const std::string& key, std::vector<int64_t> def, int64_t lo) const {
  const auto it = j_.find(key);
  if (it == j_.end()) return def;
  if (!it->is_array() || it->empty()) fail(key, "must be a non-empty list of integers, got " + it->dump());
  std::vector<int64_t> out;
  for (const auto& e : *it) {
    if (!e.is_number_integer() || e.get<int64_t>() < lo || e.get<int64_t>() > kMaxConfigDim)
      fail(key, "must hold integers >= " + std::to_string(lo) + ", got " + it->dump());
    out.push_back(e.get<int64_t>());
  }
  return out;
}

std::vector<std::string> ConfigValues::strings(const std::string& key, std::vector<std::string> def) const {
  const auto it = j_.find(key);
  if (it == j_.end()) return def;
  if (!it->is_array()) fail(key, "must be a list of strings, got " + it->dump());
  std::vector<std::string> out;
  for (const auto& e : *it) {
    if (!e.is_string()) fail(key, "must be a list of strings, got " + it->dump());
    out.push_back(e.get<std::string>());
  }
  return out;
}

int64_t ConfigValues::integer_or_default(const char* key, int64_t def, int64_t min) const {
  if (!j_.contains(key) || j_[key].is_null()) return def;
  // Bounded above too: sizes are multiplied together when memory is planned, and must not overflow there.
  if (!j_[key].is_number_integer() || (j_[key].is_number_unsigned() && j_[key].get<uint64_t>() > uint64_t(kMaxConfigDim)) ||
      j_[key].get<int64_t>() < min || j_[key].get<int64_t>() > kMaxConfigDim)
    throw Error(origin_ + ": '" + key + "' must be an integer in " + std::to_string(min) + ".." + std::to_string(kMaxConfigDim));
  return j_[key].get<int64_t>();
}

bool ConfigValues::boolean_or_default(const char* key, bool def) const {
  if (!j_.contains(key) || j_[key].is_null()) return def;
  if (!j_[key].is_boolean()) throw Error(origin_ + ": '" + key + "' must be true or false");
  return j_[key].get<bool>();
}

float ConfigValues::number_or_default(const char* key, float def) const {
  if (j_.contains(key) && j_[key].is_number()) return j_[key].get<float>();
  return def;
}

}  // namespace dvs
