#include "pipeline/cache_entry.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "dvs/error.hpp"
#include "io/crash_points.hpp"
#include "io/npy.hpp"
#include "pipeline/run_outputs.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

constexpr const char* kMarkerTag = "dvs-cache-entry";

// 64-bit FNV-1a over the bytes: a torn or altered file, not an attacker, is what the marker guards against.
uint64_t checksum(const uint8_t* p, size_t n) {
  uint64_t h = 1469598103934665603ull;
  for (size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

std::string marker_text(const std::vector<uint8_t>& bytes) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s 1 %zu %016" PRIx64 "\n", kMarkerTag, bytes.size(), checksum(bytes.data(), bytes.size()));
  return buf;
}

// "eps_inv", "latent" or "depth": the kind in an entry's name, for the crash points' names.
std::string kind_of(const fs::path& file) {
  const std::string name = file.filename().string();
  return name.substr(0, name.find('-'));
}

fs::path temporary_name(const fs::path& file) {
  static std::atomic<unsigned> n{0};
  fs::path tmp = file;
  tmp += ".tmp-" + std::to_string(::getpid()) + "-" + std::to_string(n++);
  return tmp;
}

// Writes and flushes `bytes` to the disk under a temporary name next to `file`; returns that name.
fs::path write_temporary(const fs::path& file, const void* data, size_t size) {
  const fs::path tmp = temporary_name(file);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) throw Error(file.string() + ": " + cannot_create_note(file, errno));
  size_t done = 0;
  int err = 0;
  while (done < size && !err) {
    const ssize_t w = ::write(fd, static_cast<const char*>(data) + done, size - done);
    if (w < 0 && errno != EINTR) err = errno;
    if (w > 0) done += size_t(w);
  }
  // fsync: the rename that follows must not publish a name whose bytes a power loss could still take away.
  if (!err && ::fsync(fd) != 0) err = errno;
  if (::close(fd) != 0 && !err) err = errno;
  if (err) {
    std::error_code ec;
    fs::remove(tmp, ec);
    throw Error(file.string() + ": cannot write the cache entry (" + std::strerror(err) + ")");
  }
  return tmp;
}

void publish(const fs::path& tmp, const fs::path& file) {
  std::error_code ec;
  fs::rename(tmp, file, ec);
  if (ec) {
    const std::string why = ec.message();
    fs::remove(tmp, ec);
    throw Error(file.string() + ": cannot move the finished cache entry into place (" + why + ")");
  }
}

}  // namespace

CacheFolderLock::CacheFolderLock(const fs::path& dir, bool exclusive) {
  const fs::path lock = dir / ".dvs-cache-lock";
  fd_ = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0) fd_ = ::open(lock.c_str(), O_RDONLY | O_CLOEXEC);  // a read-only cache: readers still share it
  if (fd_ < 0) return;
  while (::flock(fd_, exclusive ? LOCK_EX : LOCK_SH) != 0 && errno == EINTR) {
  }
}

CacheFolderLock::~CacheFolderLock() {
  if (fd_ >= 0) ::close(fd_);  // closing releases the flock
}

fs::path commit_marker(const fs::path& entry) {
  fs::path m = entry;
  m += ".sum";
  return m;
}

void write_cache_entry(const fs::path& file, const HostTensor& t) {
  const std::vector<uint8_t> bytes = encode_npy(t);
  const std::string marker = marker_text(bytes);
  crash_point("cache-write", kind_of(file));
  const fs::path data_tmp = write_temporary(file, bytes.data(), bytes.size());
  fs::path marker_tmp;
  try {
    marker_tmp = write_temporary(commit_marker(file), marker.data(), marker.size());
  } catch (const Error&) {
    std::error_code ec;
    fs::remove(data_tmp, ec);
    throw;
  }
  const CacheFolderLock lock(file.parent_path(), true);
  crash_point("cache-publish-before", kind_of(file));
  std::error_code ec;
  fs::remove(commit_marker(file), ec);  // an older entry of this name stops being one before its data is replaced
  publish(data_tmp, file);
  crash_point("cache-publish-data", kind_of(file));
  publish(marker_tmp, commit_marker(file));
  crash_point("cache-publish-after", kind_of(file));
  remove_stale_temporaries(file);  // what a writer of this entry killed earlier left
  remove_stale_temporaries(commit_marker(file));
}

CacheEntryRead read_cache_entry(const fs::path& file) {
  CacheEntryRead r;
  std::error_code ec;
  if (!fs::exists(file, ec)) return r;
  const CacheFolderLock lock(file.parent_path(), false);
  std::ifstream marker_in(commit_marker(file));
  std::string tag;
  int version = 0;
  uint64_t size = 0;
  std::string sum;
  if (!(marker_in >> tag >> version >> size >> sum) || tag != kMarkerTag || version != 1) {
    if (!fs::exists(file, ec)) return r;  // removed meanwhile (dvs cache clean): as good as absent
    r.problem = marker_in.is_open() ? "its commit marker " + commit_marker(file).filename().string() + " is damaged"
                                    : "it has no commit marker (a write that was interrupted, or an entry of an older dvs)";
    return r;
  }
  std::ifstream in(file, std::ios::binary);
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  char have[17];
  std::snprintf(have, sizeof have, "%016" PRIx64, checksum(bytes.data(), bytes.size()));
  if (bytes.size() != size) {
    r.problem = "it holds " + std::to_string(bytes.size()) + " bytes, its commit marker says " + std::to_string(size) + " (torn)";
    return r;
  }
  if (sum != have) {
    r.problem = "its bytes do not match the checksum in its commit marker (damaged)";
    return r;
  }
  try {
    r.tensor = parse_npy(bytes, file.string());
  } catch (const Error& e) {
    r.problem = e.what();
  }
  return r;
}

void remove_cache_entry(const fs::path& file) {
  const CacheFolderLock lock(file.parent_path(), true);
  std::error_code ec;
  fs::remove(commit_marker(file), ec);
  fs::remove(file, ec);
}

bool cache_entry_exists(const fs::path& file) {
  std::error_code ec;
  return fs::is_regular_file(file, ec) && fs::is_regular_file(commit_marker(file), ec);
}

}  // namespace dvs
