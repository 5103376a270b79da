#include "io/disk_space.hpp"

#include <sys/statvfs.h>

#include <cerrno>
#include <cstring>

namespace dvs {

std::string no_space_note(const std::filesystem::path& folder) {
  const std::filesystem::path dir = folder.empty() ? std::filesystem::path(".") : folder;
  struct statvfs s {};
  if (::statvfs(dir.c_str(), &s) != 0) return "";
  const uint64_t free_bytes = uint64_t(s.f_bavail) * uint64_t(s.f_frsize);
  if (free_bytes >= kNearlyFullBytes) return "";
  return "no space left on device (" + dir.string() + " has " + std::to_string(free_bytes) + " bytes free)";
}

std::string write_error_note(int err, const std::filesystem::path& folder) {
  const std::string dir = folder.empty() ? std::string(".") : folder.string();
  if (err == ENOSPC)
    return "no space left on device (disk full); free space on the disk holding " + dir + " or write elsewhere, "
           "then run the same command again";
  if (err == EIO)
    return "an I/O error (EIO) from the storage holding " + dir + "; check the disk or network filesystem (dmesg "
           "names the device) or write elsewhere, then run the same command again";
  return std::string(std::strerror(err)) + " (errno " + std::to_string(err) + ")";
}

}  // namespace dvs
