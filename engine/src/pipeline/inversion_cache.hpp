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
  Tensor load(vk::Context& ctx, const std::string& key, const Shape& shape) const;  // undefined when absent
  void store(vk::Context& ctx, const std::string& key, const Tensor& latent) const;
  std::filesystem::path file(const std::string& key) const;

 private:
  std::filesystem::path dir_;
};

// A stable fingerprint of a model folder: every JSON config and every weight file's size and header.
std::string model_fingerprint(const std::filesystem::path& model);
// A fingerprint of a file's bytes, or of every file below a folder (depth image sequences).
std::string file_fingerprint(const std::filesystem::path& path);

}  // namespace dvs
