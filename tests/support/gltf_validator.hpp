// The Khronos glTF validator (npm package gltf-validator, installed by .ci/deps into DVS_NODE_TOOLS, default
// ~/.cache/dvs/node) run on a file through tests/support/validate_gltf.cjs.
#pragma once
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>

#include "support/process.hpp"

namespace dvs::test {

// The validator's package folder, or nothing when node or the package is missing.
inline std::optional<std::filesystem::path> gltf_validator_dir() {
  const char* env = std::getenv("DVS_NODE_TOOLS");
  const char* home = std::getenv("HOME");
  std::filesystem::path tools = env && *env ? std::filesystem::path(env)
                                            : std::filesystem::path(home ? home : "/root") / ".cache/dvs/node";
  std::filesystem::path pkg = tools / "node_modules" / "gltf-validator";
  if (!std::filesystem::exists(pkg / "package.json")) return std::nullopt;
  if (run_command("node --version").exit_code != 0) return std::nullopt;
  return pkg;
}

// Under CI (CI=true) a missing validator is a failure, never a skip: the check must run there.
inline bool in_ci() {
  const char* ci = std::getenv("CI");
  return ci && std::string(ci) == "true";
}

inline CommandResult validate_gltf(const std::filesystem::path& validator, const std::filesystem::path& file) {
  return run_command("node " + (std::filesystem::path(DVS_SOURCE_DIR) / "tests/support/validate_gltf.cjs").string() + " " +
                     validator.string() + " " + file.string());
}

}  // namespace dvs::test

// In a TEST body: the validator's folder, or FAIL under CI / skip (saying why) elsewhere when it is missing.
#define DVS_REQUIRE_GLTF_VALIDATOR(var)                                                                          \
  const auto var##_opt = ::dvs::test::gltf_validator_dir();                                                      \
  if (!var##_opt) {                                                                                              \
    if (::dvs::test::in_ci()) FAIL() << "CI=true but the glTF validator is missing: run bash .ci/deps (node + " \
                                        "npm package gltf-validator into $DVS_NODE_TOOLS or ~/.cache/dvs/node)"; \
    GTEST_SKIP() << "glTF validator not installed (bash .ci/deps installs it); skipped outside CI";              \
  }                                                                                                              \
  const std::filesystem::path var = *var##_opt
