// Inversion results on disk, keyed by a hash of everything they depend on (the model, the encoded render,
// the image latent and the inversion settings), so a second run with another guidance, k or seed skips
// the inversion. Files are .npy written atomically; a damaged or mismatched file is ignored.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "tensor/tensor.hpp"

namespace dvs {

class InversionCache {
 public:
  explicit InversionCache(std::filesystem::path dir = {});  // empty: $DVS_CACHE_DIR or ~/.cache/dvs, + /inversions
  static std::string key(const std::vector<std::string>& parts);
  // Undefined when absent. An entry that is not a finite f32 array of `shape` (damaged, truncated, NaN/Inf) is
  // never reused: it is removed and `rejected` (when given) says why.
  Tensor load(vk::Context& ctx, const std::string& key, const Shape& shape, std::string* rejected = nullptr) const;
  void store(vk::Context& ctx, const std::string& key, const Tensor& latent) const;
  std::filesystem::path file(const std::string& key) const;
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_;
};

// A stable fingerprint of a model folder: every JSON config and every weight file's size and header.
std::string model_fingerprint(const std::filesystem::path& model);
// A fingerprint of a file's bytes, or of every file below a folder (depth image sequences).
std::string file_fingerprint(const std::filesystem::path& path);

}  // namespace dvs
