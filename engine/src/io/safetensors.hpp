// A read-only, memory-mapped .safetensors file with a fully validated header.
//
// Layout: 8-byte little-endian header length N, N bytes of UTF-8 JSON, then the data section. The JSON
// maps tensor names to {"dtype", "shape", "data_offsets": [begin, end]} (offsets relative to the data
// section) plus an optional "__metadata__" string->string map. open() checks every field, every size (with
// overflow checks) and that no two tensors share bytes, so later reads never go out of bounds.
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "io/dtype.hpp"
#include "io/host_tensor.hpp"
#include "io/weight_file.hpp"

namespace dvs {

// Bytes per element of a safetensors dtype name ("F32", "BF16", "F8_E4M3", ...), or 0 if unknown.
size_t safetensors_dtype_size(std::string_view name);
// The engine dtype for a safetensors dtype name (F32 F16 BF16 I32 U8), or nullopt.
std::optional<DType> safetensors_engine_dtype(std::string_view name);
// The safetensors name of an engine dtype ("F32", ...).
const char* safetensors_dtype_name(DType t);

// A tensor of the file (name, dtype as in the file, shape: WeightEntry) and where its bytes are. open() checks
// that the range holds exactly nbytes().
struct TensorInfo : WeightEntry {
  uint64_t begin = 0, end = 0;  // byte range inside the data section
};

class SafetensorsFile final : public WeightFile {
 public:
  // Maps and validates the file. Throws dvs::Error naming the file, the tensor and the problem.
  static SafetensorsFile open(const std::filesystem::path& path);

  SafetensorsFile(SafetensorsFile&& o) noexcept;
  SafetensorsFile& operator=(SafetensorsFile&& o) noexcept;
  SafetensorsFile(const SafetensorsFile&) = delete;
  SafetensorsFile& operator=(const SafetensorsFile&) = delete;
  ~SafetensorsFile() override;

  const std::filesystem::path& path() const override { return path_; }
  const char* format_name() const override { return "safetensors"; }
  uint64_t file_size() const { return size_; }
  uint64_t header_size() const { return header_len_; }  // N, the JSON header's length
  uint64_t data_size() const { return size_ - 8 - header_len_; }

  // Tensors sorted by name.
  const std::vector<TensorInfo>& tensors() const { return tensors_; }
  std::vector<const WeightEntry*> entries() const override;
  const TensorInfo* find(std::string_view name) const override;
  const std::map<std::string, std::string>& metadata() const override { return metadata_; }

  // The tensor's bytes inside the mapping (valid while this object lives; no alignment guarantee).
  std::span<const uint8_t> bytes(const TensorInfo& t) const;
  TensorBytes bytes(const WeightEntry& t) const override;  // the same view, through the common face
  // A copy of an engine-dtype tensor (by entry, or by name: WeightFile::load); throws for unknown names and
  // non-engine dtypes.
  using WeightFile::load;
  HostTensor load(const WeightEntry& t) const override;

 private:
  SafetensorsFile() = default;
  void parse_header();

  std::filesystem::path path_;
  const uint8_t* map_ = nullptr;
  uint64_t size_ = 0;
  uint64_t header_len_ = 0;
  std::vector<TensorInfo> tensors_;
  std::unordered_map<std::string, size_t> index_;
  std::map<std::string, std::string> metadata_;
};

}  // namespace dvs
