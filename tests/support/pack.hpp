// The conformance pack the golden tests read (DVS_GOLDEN_DIR, else tests/golden/A): its files, its cases.json
// (tolerances and recorded settings) and the VAE's latent scaling factor, so every golden test runs on any
// pack of this format.
#pragma once
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "io/npy.hpp"
#include "support/files.hpp"

namespace dvs::test {

inline HostTensor pack_npy(const std::string& rel) { return read_npy(golden_path() / rel); }

inline const nlohmann::json& pack_cases() {
  static const nlohmann::json j = nlohmann::json::parse(std::ifstream(golden_path() / "cases.json"));
  return j;
}

inline const nlohmann::json& pack_case(const std::string& name) {
  for (const auto& c : pack_cases().at("cases"))
    if (c.at("name") == name) return c;
  throw std::runtime_error("cases.json has no case " + name);
}

struct PackTolerance {
  double atol, rtol;  // |ours − golden| ≤ atol + rtol·|golden|
};

// A tolerance entry of cases.json: {"atol": .., "rtol": ..}.
inline PackTolerance tolerance_of(const nlohmann::json& t) {
  return {t.at("atol").get<double>(), t.at("rtol").get<double>()};
}

// Case `name`'s tolerance; `part` selects a sub-entry (bf16_sharded: "t5", "transformer").
inline PackTolerance pack_tolerance(const std::string& name, const std::string& part = {}) {
  const auto& t = pack_case(name).at("tolerance");
  return tolerance_of(part.empty() ? t : t.at(part));
}

// Diffusion latent = scaling_factor × VAE latent, from the pack's VAE config.
inline float pack_scaling() {
  return nlohmann::json::parse(std::ifstream(golden_path() / "model" / "vae" / "config.json"))
      .at("scaling_factor")
      .get<float>();
}

// The numbers captured by `pattern` (one group, the whole file name) among the files of the pack folder
// `dir`, ascending: e.g. the timesteps of the step files present.
inline std::vector<int> pack_file_numbers(const std::string& dir, const std::string& pattern) {
  const std::regex re(pattern);
  std::set<int> found;
  for (const auto& e : std::filesystem::directory_iterator(golden_path() / dir)) {
    std::smatch m;
    const std::string name = e.path().filename().string();
    if (std::regex_match(name, m, re)) found.insert(std::stoi(m[1]));
  }
  return {found.begin(), found.end()};
}

}  // namespace dvs::test
