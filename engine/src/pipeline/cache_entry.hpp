// One tensor of the cache folder (an inversion, a sampled latent, a depth estimate) as a verifiable entry:
// NAME.npy, a plain .npy file, and its commit marker NAME.npy.sum ("dvs-cache-entry 1 <bytes> <checksum>"),
// written last. Both are written under temporary names (NAME.tmp-PID-N, which `dvs cache clean` knows) and
// renamed into place while the folder's lock (DIR/.dvs-cache-lock, flock) is held exclusively; readers hold it
// shared while they read and verify. So a reader never sees half an entry, two processes publishing the same
// entry each leave a whole one (the second replaces the first's with its own, equal pair), and an entry torn by
// a crash (the data without its marker, or bytes that do not match it) is reported and never used.
#pragma once
#include <filesystem>
#include <optional>
#include <string>

#include "io/host_tensor.hpp"

namespace dvs {

// The folder's lock, held for the object's lifetime; without it (a read-only folder) nothing is locked.
class CacheFolderLock {
 public:
  CacheFolderLock(const std::filesystem::path& dir, bool exclusive);
  ~CacheFolderLock();
  CacheFolderLock(const CacheFolderLock&) = delete;
  CacheFolderLock& operator=(const CacheFolderLock&) = delete;

 private:
  int fd_ = -1;
};

std::filesystem::path commit_marker(const std::filesystem::path& entry);

// Writes `t` as the entry `file` and its marker. Throws dvs::Error naming the file when it cannot be written.
void write_cache_entry(const std::filesystem::path& file, const HostTensor& t);

struct CacheEntryRead {
  std::optional<HostTensor> tensor;  // the verified contents
  std::string problem;               // why the entry there cannot be used; empty when there is none
};
// The entry `file`: neither tensor nor problem when there is none.
CacheEntryRead read_cache_entry(const std::filesystem::path& file);

// Removes a damaged entry: its marker first (from then on it is no entry), then its data.
void remove_cache_entry(const std::filesystem::path& file);

// Whether `file` and its marker are both there (a cheap look, not a verification).
bool cache_entry_exists(const std::filesystem::path& file);

}  // namespace dvs
