#include "io/weight_file.hpp"

#include <fstream>

#include "dvs/error.hpp"
#include "io/pth_file.hpp"
#include "io/safetensors.hpp"

namespace dvs {

WeightFormat weight_file_format(const std::filesystem::path& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error(path.string() + ": no such weight file");
  if (!std::filesystem::is_regular_file(path, ec)) throw Error(path.string() + ": not a regular file (expected a weight file)");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path.string() + ": cannot read the weight file");
  unsigned char head[9] = {};
  in.read(reinterpret_cast<char*>(head), sizeof head);
  const std::streamsize got = in.gcount();
  // A zip archive starts with a local file header, or (no members) with the end-of-central-directory record.
  if (got >= 4 && head[0] == 'P' && head[1] == 'K' && ((head[2] == 3 && head[3] == 4) || (head[2] == 5 && head[3] == 6)))
    return WeightFormat::pth;
  if (got == 9 && head[8] == '{') return WeightFormat::safetensors;
  return WeightFormat::neither;
}

std::unique_ptr<WeightFile> WeightFile::open(const std::filesystem::path& path) {
  switch (weight_file_format(path)) {
    case WeightFormat::pth: return std::make_unique<PthFile>(PthFile::open(path));
    case WeightFormat::safetensors: return std::make_unique<SafetensorsFile>(SafetensorsFile::open(path));
    case WeightFormat::neither: break;
  }
  throw Error(path.string() + ": not a weight file dvs reads: neither safetensors (an 8-byte header length, then a "
              "JSON header starting with '{') nor a PyTorch checkpoint (a zip archive, torch.save's format since "
              "torch 1.6); the file may be truncated, or another format (re-download it, or convert it to "
              "safetensors)");
}

const std::map<std::string, std::string>& WeightFile::metadata() const {
  static const std::map<std::string, std::string> none;
  return none;
}

HostTensor WeightFile::load(std::string_view name) const {
  const WeightEntry* t = find(name);
  if (!t) throw Error(path().string() + ": no tensor named '" + std::string(name) + "'");
  return load(*t);
}

void WeightFile::throw_not_ours(const WeightEntry& entry) const {
  throw Error(path().string() + ": tensor '" + entry.name + "' is not from this file");
}

}  // namespace dvs
