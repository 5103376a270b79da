// The weights of one component or one checkpoint, whatever the files: one weight file of either format
// (io/weight_file.hpp: safetensors or PyTorch .pth, told apart by content), or safetensors shards listed by a
// *.safetensors.index.json, merged into one name -> tensor map. The one loader of every model's weights.
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
#include "io/weight_file.hpp"

namespace dvs {

// Where one weight lives: the file that holds it and its entry there.
struct WeightRef {
  const WeightFile* file = nullptr;
  const WeightEntry* info = nullptr;
};

// All weights of one component, merged across shards. Owns the mapped files.
class WeightSet {
 public:
  // Finds the weights in a component folder: `model.safetensors` / `diffusion_pytorch_model.safetensors`,
  // else their `.index.json` shard index, else the only *.safetensors or *.safetensors.index.json present.
  static WeightSet open_dir(const std::filesystem::path& dir);
  // One file: a *.json is a shard index naming safetensors shards next to it; any other name is one weight file
  // of the format its content shows (safetensors or .pth, whatever its extension), or an error naming it.
  static WeightSet open_file(const std::filesystem::path& file);
  // Whether `dir` holds any *.safetensors weights at all (tokenizer/scheduler folders do not).
  static bool dir_has_weights(const std::filesystem::path& dir);

  const std::filesystem::path& source() const { return source_; }  // the weight file or the index file
  bool sharded() const { return sharded_; }
  const std::vector<std::unique_ptr<WeightFile>>& files() const { return files_; }
  // Name -> location, sorted by name.
  const std::map<std::string, WeightRef, std::less<>>& entries() const { return entries_; }
  size_t size() const { return entries_.size(); }
  const WeightRef* find(std::string_view name) const;
  TensorBytes bytes(std::string_view name) const;               // throws if absent
  HostTensor load(std::string_view name) const;                 // throws if absent / not an engine dtype
  uint64_t total_bytes() const;
  // Non-fatal findings (tensors in a shard that the index does not list, total_size mismatch).
  const std::vector<std::string>& warnings() const { return warnings_; }

 private:
  void add_file_tensors(const WeightFile& f);
  static WeightSet open_index(const std::filesystem::path& index);

  std::filesystem::path source_;
  bool sharded_ = false;
  std::vector<std::unique_ptr<WeightFile>> files_;
  std::map<std::string, WeightRef, std::less<>> entries_;
  std::vector<std::string> warnings_;
};

}  // namespace dvs
