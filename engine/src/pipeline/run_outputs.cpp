#include "pipeline/run_outputs.hpp"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>

#include <atomic>
#include <fstream>

#include "dvs/error.hpp"
#include "io/crash_points.hpp"

namespace dvs {

namespace {

constexpr const char* kStagingPrefix = ".dvs-partial-";
constexpr const char* kJournal = "COMMIT";

// Moves the staged files named in `staging`/COMMIT into `dir`, in their order; true when there was a COMMIT.
bool roll_forward(const std::filesystem::path& staging, const std::filesystem::path& dir) {
  std::ifstream in(staging / kJournal);
  if (!in) return false;
  std::error_code ec;
  for (std::string name; std::getline(in, name);) {
    // Only plain names of this folder: a damaged journal must not move anything elsewhere.
    if (name.empty() || name != std::filesystem::path(name).filename().string() || name[0] == '.') continue;
    if (std::filesystem::is_regular_file(staging / name, ec)) std::filesystem::rename(staging / name, dir / name, ec);
  }
  return true;
}

}  // namespace

bool process_is_gone(long pid) { return pid > 0 && ::kill(pid_t(pid), 0) != 0 && errno == ESRCH; }

void recover_staging(const std::filesystem::path& dir, bool locked) {
  std::error_code ec;
  std::vector<std::filesystem::path> staged;
  for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind(kStagingPrefix, 0) != 0 || !e.is_directory(ec)) continue;
    const long pid = std::strtol(name.c_str() + std::strlen(kStagingPrefix), nullptr, 10);
    if (locked || process_is_gone(pid)) staged.push_back(e.path());
  }
  for (const auto& s : staged) {
    roll_forward(s, dir);
    std::filesystem::remove_all(s, ec);
  }
}

void remove_stale_temporaries(const std::filesystem::path& file) {
  const std::string name = file.filename().string();
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(file.parent_path(), ec)) {
    const std::string other = e.path().filename().string();
    if (other.rfind(name, 0) != 0) continue;
    long pid = 0;
    for (const char* mark : {".tmp-", ".partial-"})
      if (other.compare(name.size(), std::strlen(mark), mark) == 0)
        pid = std::strtol(other.c_str() + name.size() + std::strlen(mark), nullptr, 10);
    if (process_is_gone(pid)) std::filesystem::remove(e.path(), ec);
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

std::string RunOutputs::with_final_paths(std::string text) const {
  const std::string from = staging_.string(), to = dir_.string();
  for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size()))
    text.replace(at, from.size(), to);
  return text;
}

std::filesystem::path RunOutputs::add(const std::string& name) {
  names_.push_back(name);
  return staging_ / name;
}

void RunOutputs::commit() {
  // The journal, whole or not at all: from its rename on, the job's files are the folder's.
  const std::filesystem::path journal_tmp = staging_ / (std::string(kJournal) + ".tmp");
  {
    std::ofstream journal(journal_tmp);
    for (const auto& name : names_) journal << name << "\n";
    if (!journal.flush())
      throw Error(journal_tmp.string() + ": cannot write the list of finished files; nothing in " + dir_.string() + " was replaced");
  }
  crash_point("publish-journal-before");
  std::error_code ec;
  std::filesystem::rename(journal_tmp, staging_ / kJournal, ec);
  if (ec) throw Error(journal_tmp.string() + ": cannot finish the list of finished files (" + ec.message() + ")");
  journaled_ = true;
  for (const auto& name : names_) {
    crash_point("publish-before", name);
    std::filesystem::rename(staging_ / name, dir_ / name, ec);
    if (ec)
      throw Error((dir_ / name).string() + ": cannot move the finished file into place (" + ec.message() +
                  "); the staged copy was in " + staging_.string());
    crash_point("publish-after", name);
  }
  std::filesystem::remove_all(staging_, ec);
  journaled_ = false;
  crash_point("publish-done");
}

RunOutputs::~RunOutputs() {
  std::error_code ec;
  if (!journaled_) std::filesystem::remove_all(staging_, ec);
}

}  // namespace dvs
