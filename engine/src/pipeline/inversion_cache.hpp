// Inversion results on disk, keyed by a hash of everything they depend on (the model, the encoded render,
// the image latent and the inversion settings), so a second run with another guidance, k or seed skips
// the inversion. Entries are verified .npy files (pipeline/cache_entry.hpp); a damaged or mismatched one is
// removed and computed again. The same folder
// keeps the runs' sampled latents under another prefix (job_stages.hpp: LatentCache).
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "tensor/tensor.hpp"

namespace dvs {

class InversionCache {
 public:
  // cache_dir: the cache folder (io/cache_root.hpp; empty: $DVS_CACHE_DIR or ~/.cache/dvs); the entries are
  // <prefix>-<key>.npy in its inversions/ folder.
  explicit InversionCache(const std::filesystem::path& cache_dir = {}, std::string prefix = "eps_inv");
  static std::string key(const std::vector<std::string>& parts);
  // The same hash of `bytes` bytes in memory (a clip handed over in memory is named by its contents).
  static std::string bytes_key(const void* data, size_t bytes);
  // Undefined when absent. An entry that is not a finite f32 array of `shape` (damaged, truncated, NaN/Inf) is
  // never reused: it is removed and `rejected` (when given) says why.
  Tensor load(vk::Context& ctx, const std::string& key, const Shape& shape, std::string* rejected = nullptr) const;
  // Empty when the entry was written; else why not (the caller warns: an unwritable cache costs only time).
  [[nodiscard]] std::string store(vk::Context& ctx, const std::string& key, const Tensor& latent) const;
  std::filesystem::path file(const std::string& key) const;
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
  std::string prefix_;
};

// A stable fingerprint of a model folder: every JSON config and every weight file's size and header.
std::string model_fingerprint(const std::filesystem::path& model);
// A fingerprint of a file's bytes, or of every file below a folder (depth image sequences).
std::string file_fingerprint(const std::filesystem::path& path);

}  // namespace dvs
