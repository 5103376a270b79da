// The source tree (tests/data, the in-repo packs): DVS_SOURCE_DIR in the environment when the tests run from a
// relocated bundle (bench/gpu/run.sh), else the tree this build was configured from.
#pragma once
#include <cstdlib>
#include <filesystem>

namespace dvs::test {

inline std::filesystem::path source_dir() {
  const char* e = std::getenv("DVS_SOURCE_DIR");
  return e && *e ? std::filesystem::path(e) : std::filesystem::path(DVS_SOURCE_DIR);
}

}  // namespace dvs::test
