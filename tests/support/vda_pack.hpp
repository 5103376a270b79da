// The Video-Depth-Anything conformance pack (DVS_VDA_GOLDEN_DIR, else tests/golden/vda-A): its folder, its
// cases.json and model/config.json, so tests take sizes, keys and tolerances from the pack, never from code.
#pragma once
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

namespace dvs::test {

inline std::filesystem::path vda_golden_path() {
  const char* e = std::getenv("DVS_VDA_GOLDEN_DIR");
  return e && *e ? std::filesystem::path(e) : std::filesystem::path(DVS_DEFAULT_VDA_GOLDEN_DIR);
}

inline nlohmann::json vda_read_json(const std::filesystem::path& p) {
  std::ifstream in(p);
  if (!in) throw std::runtime_error(p.string() + ": missing (set DVS_VDA_GOLDEN_DIR to a vda conformance pack)");
  return nlohmann::json::parse(in);
}

inline const nlohmann::json& vda_cases() {
  static const nlohmann::json j = vda_read_json(vda_golden_path() / "cases.json");
  return j;
}

inline const nlohmann::json& vda_model_config() {
  static const nlohmann::json j = vda_read_json(vda_golden_path() / "model" / "config.json");
  return j;
}

inline const nlohmann::json& vda_case(const std::string& name) {
  for (const auto& c : vda_cases().at("cases"))
    if (c.at("name") == name) return c;
  throw std::runtime_error("vda cases.json has no case " + name);
}

// The pack's checkpoint file (cases.json -> checkpoint.file, relative to the pack).
inline std::filesystem::path vda_checkpoint_path() {
  return vda_golden_path() / vda_cases().at("checkpoint").at("file").get<std::string>();
}

}  // namespace dvs::test
