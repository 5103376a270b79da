#include "io/disk_space.hpp"

#include <sys/statvfs.h>

namespace dvs {

std::string no_space_note(const std::filesystem::path& folder) {
  const std::filesystem::path dir = folder.empty() ? std::filesystem::path(".") : folder;
  struct statvfs s {};
  if (::statvfs(dir.c_str(), &s) != 0) return "";
  const uint64_t free_bytes = uint64_t(s.f_bavail) * uint64_t(s.f_frsize);
  if (free_bytes >= kNearlyFullBytes) return "";
  return "no space left on device (" + dir.string() + " has " + std::to_string(free_bytes) + " bytes free)";
}

}  // namespace dvs
