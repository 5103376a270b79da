#include "pipeline/output_path.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace dvs {
namespace {

// The first existing path at or above `p` (the folder need not exist yet).
std::filesystem::path existing_ancestor(std::filesystem::path p) {
  std::error_code ec;
  p = std::filesystem::absolute(p, ec);
  while (!p.empty() && !std::filesystem::exists(p, ec) && p != p.parent_path()) p = p.parent_path();
  return p;
}

}  // namespace

std::optional<std::string> folder_write_problem(const std::filesystem::path& dir, const std::string& fix) {
  std::error_code ec;
  const auto abs = std::filesystem::absolute(dir, ec);
  if (std::filesystem::exists(abs, ec) && !std::filesystem::is_directory(abs, ec))
    return dir.string() + ": exists and is not a folder (" + fix + ")";
  const auto base = existing_ancestor(abs);
  if (!std::filesystem::is_directory(base, ec))
    return dir.string() + ": cannot be created, " + base.string() + " is not a folder (" + fix + ")";
  if (::access(base.c_str(), W_OK | X_OK) != 0) return dir.string() + ": " + base.string() + " is not writable (" + fix + ")";
  return std::nullopt;
}

std::optional<std::string> file_write_problem(const std::filesystem::path& file, const std::string& fix) {
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) return file.string() + ": is a folder; give a file name (" + fix + ")";
  const auto folder = std::filesystem::absolute(file, ec).parent_path();
  if (auto p = folder_write_problem(folder, fix)) return file.string() + ": its folder " + *p;
  if (!std::filesystem::is_directory(folder, ec)) return std::nullopt;  // created below a writable folder later
  // Try it: permissions say nothing for root, and nothing about a read-only or full file system.
  const std::string probe = (folder / ("." + file.filename().string() + ".write-check")).string();
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
  if (fd < 0) {
    const int err = errno;
    if (err == EEXIST) return std::nullopt;  // a leftover probe: the folder took a file before
    return file.string() + ": cannot create a file in " + folder.string() + " (" + std::strerror(err) + "; " + fix + ")";
  }
  ::close(fd);
  ::unlink(probe.c_str());
  return std::nullopt;
}

}  // namespace dvs
