// One checkpoint file, whatever its format: the tensors it holds (name, dtype, shape), the bytes of one, where it
// came from and which format it is. SafetensorsFile (io/safetensors.hpp) and PthFile (io/pth_file.hpp) implement
// it; WeightFile::open picks between them by the file's first bytes, never by its name, so a checkpoint renamed
// (a .pth saved as .bin, a safetensors file without its extension) still opens as what it is.
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "io/dtype.hpp"
#include "io/host_tensor.hpp"

namespace dvs {

// What every format says about one tensor. Each format's entry adds where its bytes are.
struct WeightEntry {
  std::string name;
  std::string dtype_name;      // safetensors naming: "F32", "BF16", "I64", ...
  std::optional<DType> dtype;  // set when the engine can use it directly (F32 F16 BF16 I32 U8)
  size_t elem_size = 0;        // bytes per element
  Shape shape;
  uint64_t numel = 0;

  uint64_t nbytes() const { return numel * elem_size; }  // of the contiguous tensor
};

// A tensor's bytes, row-major and contiguous: a view into a mapped file (safetensors), or a copy read out of an
// archive (.pth). Converts to a span that is valid while this object lives.
class TensorBytes {
 public:
  explicit TensorBytes(std::span<const uint8_t> view) : view_(view) {}
  explicit TensorBytes(std::vector<uint8_t> copy) : copy_(std::move(copy)), view_(copy_) {}
  TensorBytes(TensorBytes&&) = default;  // the copy's buffer moves with it, so the view stays valid
  TensorBytes(const TensorBytes&) = delete;
  TensorBytes& operator=(const TensorBytes&) = delete;

  std::span<const uint8_t> span() const { return view_; }
  operator std::span<const uint8_t>() const { return view_; }
  const uint8_t* data() const { return view_.data(); }
  size_t size() const { return view_.size(); }
  bool empty() const { return view_.empty(); }

 private:
  std::vector<uint8_t> copy_;
  std::span<const uint8_t> view_;
};

// The formats WeightFile::open tells apart by content.
enum class WeightFormat { safetensors, pth, neither };

// The format `path`'s first bytes show: a zip archive (torch.save's format since torch 1.6) is a .pth, an 8-byte
// header length followed by '{' a safetensors file. Throws dvs::Error naming the file when it cannot be read.
WeightFormat weight_file_format(const std::filesystem::path& path);

class WeightFile {
 public:
  virtual ~WeightFile() = default;

  // Opens `path` as the format its content shows (weight_file_format). A file of neither format is a dvs::Error
  // naming it and saying what each format starts with.
  static std::unique_ptr<WeightFile> open(const std::filesystem::path& path);

  virtual const std::filesystem::path& path() const = 0;
  virtual const char* format_name() const = 0;  // "safetensors", "PyTorch .pth"
  // The tensors in the file's order (safetensors: by name; .pth: the state_dict's).
  virtual std::vector<const WeightEntry*> entries() const = 0;
  virtual const WeightEntry* find(std::string_view name) const = 0;
  // `entry` must be one of this file's (an error names it otherwise).
  virtual TensorBytes bytes(const WeightEntry& entry) const = 0;
  // A copy as a HostTensor in the stored dtype; throws for dtypes the engine has no DType for.
  virtual HostTensor load(const WeightEntry& entry) const = 0;
  // The same by name; dvs::Error naming the file and the tensor when it has none.
  HostTensor load(std::string_view name) const;
  // String metadata stored with the tensors (safetensors' __metadata__); empty when the format has none.
  virtual const std::map<std::string, std::string>& metadata() const;

 protected:
  // Every entry of a format's tensor list, in its order (for entries()).
  template <class Info>
  static std::vector<const WeightEntry*> entry_list(const std::vector<Info>& infos) {
    std::vector<const WeightEntry*> out;
    out.reserve(infos.size());
    for (const Info& i : infos) out.push_back(&i);
    return out;
  }
  // The format's own entry for `entry`, checked to be this file's (`info` is what find(entry.name) returned).
  template <class Info>
  const Info& own_entry(const Info* info, const WeightEntry& entry) const {
    if (info != &entry) throw_not_ours(entry);
    return *info;
  }

 private:
  [[noreturn]] void throw_not_ours(const WeightEntry& entry) const;
};

}  // namespace dvs
