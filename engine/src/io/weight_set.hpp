// The weights of one component, whatever the files: one *.safetensors, or shards listed by a
// *.safetensors.index.json, merged into one name -> tensor map.
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "io/host_tensor.hpp"
#include "io/safetensors.hpp"

namespace dvs {

// Where one weight lives: the (mapped) file that holds it and its header entry.
struct WeightRef {
  const SafetensorsFile* file = nullptr;
  const TensorInfo* info = nullptr;
};

// All weights of one component, merged across shards. Owns the mapped files.
class WeightSet {
 public:
  // Finds the weights in a component folder: `model.safetensors` / `diffusion_pytorch_model.safetensors`,
  // else their `.index.json` shard index, else the only *.safetensors or *.safetensors.index.json present.
  static WeightSet open_dir(const std::filesystem::path& dir);
  // One file: a .safetensors, or a *.safetensors.index.json naming shards next to it.
  static WeightSet open_file(const std::filesystem::path& file);
  // Whether `dir` holds any *.safetensors weights at all (tokenizer/scheduler folders do not).
  static bool dir_has_weights(const std::filesystem::path& dir);

  const std::filesystem::path& source() const { return source_; }  // the .safetensors or the index file
  bool sharded() const { return sharded_; }
  const std::vector<std::unique_ptr<SafetensorsFile>>& files() const { return files_; }
  // Name -> location, sorted by name.
  const std::map<std::string, WeightRef, std::less<>>& entries() const { return entries_; }
  size_t size() const { return entries_.size(); }
  const WeightRef* find(std::string_view name) const;
  std::span<const uint8_t> bytes(std::string_view name) const;  // throws if absent
  HostTensor load(std::string_view name) const;                 // throws if absent / not an engine dtype
  uint64_t total_bytes() const;
  // Non-fatal findings (tensors in a shard that the index does not list, total_size mismatch).
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  void add_file_tensors(const SafetensorsFile& f);
  static WeightSet open_index(const std::filesystem::path& index);

  std::filesystem::path source_;
  bool sharded_ = false;
  std::vector<std::unique_ptr<SafetensorsFile>> files_;
  std::map<std::string, WeightRef, std::less<>> entries_;
  std::vector<std::string> warnings_;
};

}  // namespace dvs
