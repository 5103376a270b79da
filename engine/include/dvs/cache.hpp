// The cache folder: --cache-dir DIR, DVS_CACHE_DIR=DIR and the library's cache_dir (RunOptions, DepthJob,
// RenderJob::depth_cache_dir, dvs_pipeline_options) all name it; empty: $DVS_CACHE_DIR, else ~/.cache/dvs. It holds
// the Vulkan pipeline cache and, in DIR/inversions, the entries a later run reuses: depth estimates, inversions and
// sampled latents. `dvs cache list` and `dvs cache clean` read and trim the entries.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "dvs/api.hpp"

namespace dvs {

struct CacheEntry {
  std::string kind;                         // "depth", "inversion" or "latent"
  std::string key;                          // the hash of its inputs
  std::filesystem::path data_file;          // its data: the .npy a run reads
  std::vector<std::filesystem::path> files; // all its files, the commit marker (.npy.sum) first (a latent: and its .json)
  uint64_t bytes = 0;                       // all its files together
  double age_days = 0;                      // since it was last written or reused
};

// The folder the entries are in for the cache folder `cache_dir` as given: cache_dir/inversions (empty cache_dir:
// $DVS_CACHE_DIR/inversions, else ~/.cache/dvs/inversions).
DVS_API std::filesystem::path cache_folder(const std::filesystem::path& cache_dir);

// When the cache folder holds entries directly in it, as a dvs whose --cache-dir named the entries' own folder left
// them: what to do (the commands that move them, or the folder to give instead). A run on such a folder is refused
// with this message rather than computing its entries again; nullopt when there are none.
DVS_API std::optional<std::string> old_cache_layout(const std::filesystem::path& cache_dir);

// Every complete entry, most recently used first. Files still being written (a temporary name until they are
// renamed into place whole) are not entries.
DVS_API std::vector<CacheEntry> list_cache(const std::filesystem::path& cache_dir);

struct CacheCleaning {
  std::optional<double> older_than_days;  // remove entries unused for longer than this
  std::optional<uint64_t> max_bytes;      // then remove the least recently used until the rest fit in this
  bool all = false;                       // remove every entry
  bool dry_run = false;                   // say what would go, remove nothing
};

struct CacheCleaned {
  std::vector<CacheEntry> removed;
  uint64_t removed_bytes = 0, kept_bytes = 0;
  int kept = 0;
  int stale_temporaries = 0;  // files left half-written by dvs processes that no longer exist, removed
};

// Removes entries as `what` says. Never touches a file another process is writing (those have temporary names
// and are not entries); a process reading an entry while it is removed keeps reading it (POSIX unlink).
DVS_API CacheCleaned clean_cache(const std::filesystem::path& cache_dir, const CacheCleaning& what);

// "500M", "2G", "1.5GiB", "1048576" -> bytes (K/M/G/T are powers of 1024); nullopt when not a size.
DVS_API std::optional<uint64_t> parse_byte_size(const std::string& text);

}  // namespace dvs
