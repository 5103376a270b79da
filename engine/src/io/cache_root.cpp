#include "io/cache_root.hpp"

#include <cstdlib>

namespace dvs {

std::filesystem::path cache_root(const std::filesystem::path& given) {
  if (!given.empty()) return given;
  if (const char* d = std::getenv("DVS_CACHE_DIR"); d && *d) return d;
  if (const char* home = std::getenv("HOME"); home && *home) return std::filesystem::path(home) / ".cache" / "dvs";
  return std::filesystem::temp_directory_path() / "dvs-cache";
}

}  // namespace dvs
