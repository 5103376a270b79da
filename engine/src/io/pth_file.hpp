// A PyTorch `.pth` checkpoint as torch.save writes it since torch 1.6: a zip archive holding
// `<prefix>/data.pkl` (the pickled state_dict) and one raw little-endian record `<prefix>/data/<key>` per
// storage. The prefix is whatever torch chose (`archive/`, the file's stem, ...): the archive's one data.pkl
// decides it. The pickle goes through the restricted reader of pickle_state_dict.hpp, so nothing is imported or
// executed. open() checks every tensor against its storage record (presence, size, bounds with overflow-safe
// arithmetic), so later reads cannot go out of bounds; tensor bytes are read on demand (CRC-checked by libzip).
//
// Its tensors share SafetensorsFile's face (io/weight_file.hpp: name, dtype name, engine dtype, shape, bytes) so a
// model loader treats both formats alike. Not thread-safe: one PthFile reads one record at a time.
#pragma once
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "io/dtype.hpp"
#include "io/host_tensor.hpp"
#include "io/weight_file.hpp"

typedef struct zip zip_t;

namespace dvs {

// A tensor of the state_dict (name, dtype in safetensors naming: "F32", "F16", "BF16", "F64", "I64", "I32", "I16",
// "I8", "U8", "BOOL"; shape: WeightEntry) and where its values are in the archive.
struct PthTensorInfo : WeightEntry {
  // Where the values are: elements storage_offset + sum(index_i * strides_i) of record data/<storage_key>.
  std::string storage_key;
  int64_t storage_offset = 0;
  Shape strides;
  bool contiguous = true;  // row-major without gaps: read as one slice, otherwise gathered on read
};

class PthFile final : public WeightFile {
 public:
  // Opens and validates the archive. Throws dvs::Error naming the file and the problem.
  static PthFile open(const std::filesystem::path& path);

  PthFile(PthFile&& o) noexcept;
  PthFile& operator=(PthFile&& o) noexcept;
  PthFile(const PthFile&) = delete;
  PthFile& operator=(const PthFile&) = delete;
  ~PthFile() override;

  const std::filesystem::path& path() const override { return path_; }
  const char* format_name() const override { return "PyTorch .pth"; }
  const std::string& record_prefix() const { return prefix_; }  // "archive/", "video_depth_anything_vits/", ...
  // What open() normalised: the wrapper key that held the state_dict ("" if none), and whether a "module."
  // prefix shared by every key was removed.
  const std::string& unwrapped() const { return unwrapped_; }
  bool stripped_module_prefix() const { return stripped_module_; }

  // Tensors in the state_dict's order.
  const std::vector<PthTensorInfo>& tensors() const { return tensors_; }
  std::vector<const WeightEntry*> entries() const override;
  const PthTensorInfo* find(std::string_view name) const override;
  uint64_t total_bytes() const;

  // The tensor's values, row-major and contiguous (strided tensors are gathered).
  std::vector<uint8_t> read_bytes(const PthTensorInfo& t) const;
  TensorBytes bytes(const WeightEntry& t) const override;  // read_bytes, through the common face
  // A copy as a HostTensor (by entry, or by name: WeightFile::load); throws for unknown names and for dtypes the
  // engine has no DType for.
  using WeightFile::load;
  HostTensor load(const WeightEntry& t) const override;

 private:
  PthFile() = default;
  std::vector<uint8_t> read_record(const std::string& name, uint64_t expected_size) const;

  std::filesystem::path path_;
  zip_t* zip_ = nullptr;
  std::string prefix_;
  std::string unwrapped_;
  bool stripped_module_ = false;
  std::vector<PthTensorInfo> tensors_;
  std::unordered_map<std::string, size_t> index_;
  struct Record {
    uint64_t index = 0, size = 0;
  };
  std::unordered_map<std::string, Record> records_;  // storage key -> zip entry
};

}  // namespace dvs
