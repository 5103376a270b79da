#include "pipeline/run_outputs.hpp"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include <atomic>

#include "dvs/error.hpp"

namespace dvs {

namespace {
constexpr const char* kStagingPrefix = ".dvs-partial-";
}

void remove_stale_staging(const std::filesystem::path& dir) {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(kStagingPrefix, 0) != 0 || !e.is_directory(ec)) continue;
    const long pid = std::strtol(name.c_str() + std::strlen(kStagingPrefix), nullptr, 10);
    if (pid > 0 && ::kill(pid_t(pid), 0) != 0 && errno == ESRCH) std::filesystem::remove_all(e.path(), ec);
  }
}

CreatedFolders::CreatedFolders(const std::filesystem::path& dir) {
  std::error_code ec;
  for (auto p = std::filesystem::absolute(dir, ec).lexically_normal(); !p.empty() && !std::filesystem::exists(p, ec);
       p = p.parent_path()) {
    if (ec || p == p.parent_path()) break;
    missing_.push_back(p);
  }
}

CreatedFolders::~CreatedFolders() {
  for (const auto& p : missing_) {
    std::error_code ec;
    // remove() takes only an empty folder (or a file, which is not ours: then stop).
    if (!std::filesystem::is_directory(p, ec) || !std::filesystem::remove(p, ec)) break;
  }
}

RunOutputs::RunOutputs(std::filesystem::path dir) : dir_(std::move(dir)) {
  static std::atomic<int> n{0};
  staging_ = dir_ / (kStagingPrefix + std::to_string(::getpid()) + "-" + std::to_string(n++));
  std::error_code ec;
  std::filesystem::remove_all(staging_, ec);
  std::filesystem::create_directories(staging_, ec);
  if (ec) throw Error(staging_.string() + ": cannot create the staging folder for the outputs (" + ec.message() + ")");
}

std::filesystem::path RunOutputs::add(const std::string& name) {
  names_.push_back(name);
  return staging_ / name;
}

void RunOutputs::commit() {
  for (const auto& name : names_) {
    std::error_code ec;
    std::filesystem::rename(staging_ / name, dir_ / name, ec);
    if (ec)
      throw Error((dir_ / name).string() + ": cannot move the finished file into place (" + ec.message() +
                  "); the staged copy was in " + staging_.string());
  }
  committed_ = true;
  std::error_code ec;
  std::filesystem::remove_all(staging_, ec);
}

RunOutputs::~RunOutputs() {
  std::error_code ec;
  std::filesystem::remove_all(staging_, ec);
}

}  // namespace dvs
