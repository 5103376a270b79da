// Per-component weight discovery, including sharded checkpoints.
#include "io/weight_set.hpp"

#include <algorithm>
#include <set>

#include "dvs/error.hpp"
#include "io/json_file.hpp"

namespace dvs {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

bool ends_with(const std::string& s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Regular files in `dir` whose names end with `suffix`, sorted.
std::vector<fs::path> files_ending(const fs::path& dir, std::string_view suffix) {
  std::vector<fs::path> out;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.is_regular_file(ec) && ends_with(e.path().filename().string(), suffix)) out.push_back(e.path());
  std::sort(out.begin(), out.end());
  return out;
}

std::string name_list(const std::vector<fs::path>& files) {
  std::string out;
  for (const auto& f : files) {
    if (!out.empty()) out += ", ";
    out += f.filename().string();
  }
  return out;
}

}  // namespace

bool WeightSet::dir_has_weights(const fs::path& dir) {
  return !files_ending(dir, ".safetensors").empty() || !files_ending(dir, ".safetensors.index.json").empty();
}

WeightSet WeightSet::open_dir(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) throw Error(dir.string() + ": not a folder (expected a model component folder)");
  // The libraries' standard names first: transformers writes model.*, diffusers diffusion_pytorch_model.*.
  // A single file wins over an index (as transformers does), which ignores stray variants like *.fp16.*.
  for (const char* single : {"model.safetensors", "diffusion_pytorch_model.safetensors"})
    if (fs::is_regular_file(dir / single, ec)) return open_file(dir / single);
  for (const char* index : {"model.safetensors.index.json", "diffusion_pytorch_model.safetensors.index.json"})
    if (fs::is_regular_file(dir / index, ec)) return open_index(dir / index);

  const auto indexes = files_ending(dir, ".safetensors.index.json");
  if (indexes.size() == 1) return open_index(indexes[0]);
  if (indexes.size() > 1)
    throw Error(dir.string() + ": several shard indexes (" + name_list(indexes) +
                "); keep one, or open the index you want with its path");
  const auto singles = files_ending(dir, ".safetensors");
  if (singles.size() == 1) return open_file(singles[0]);
  if (singles.size() > 1)
    throw Error(dir.string() + ": several .safetensors files (" + name_list(singles) +
                ") and no *.safetensors.index.json to say which belong together; add the index or keep one file");
  if (!files_ending(dir, ".bin").empty())
    throw Error(dir.string() + ": only PyTorch .bin weights found; dvs reads safetensors (re-download the "
                "safetensors files, or convert with the library's save_pretrained(safe_serialization=True))");
  throw Error(dir.string() + ": no weights (*.safetensors) in this folder; download the component's weights "
              "(e.g. huggingface-cli download THUDM/CogVideoX-5b-I2V --local-dir <folder>)");
}

WeightSet WeightSet::open_file(const fs::path& file) {
  if (ends_with(file.filename().string(), ".json")) return open_index(file);
  WeightSet w;
  w.source_ = file;
  w.files_.push_back(WeightFile::open(file));
  w.add_file_tensors(*w.files_.back());
  return w;
}

void WeightSet::add_file_tensors(const WeightFile& f) {
  for (const WeightEntry* t : f.entries()) entries_.emplace(t->name, WeightRef{&f, t});
}

WeightSet WeightSet::open_index(const fs::path& index) {
  const std::string iname = index.string();
  const json j = read_json_file(index, "it is the shard index of a sharded checkpoint; re-download it");
  if (!j.is_object()) throw Error(iname + ": shard index is not a JSON object");
  const auto wm = j.find("weight_map");
  if (wm == j.end() || !wm->is_object())  // e.g. a config.json given where weights belong
    throw Error(iname + ": read as a sharded checkpoint's index (*.safetensors.index.json), but it has no "
                "\"weight_map\" object; give the weights file itself (.safetensors or .pth) or the folder that holds them");

  WeightSet w;
  w.source_ = index;
  w.sharded_ = true;
  const fs::path dir = index.parent_path();

  // Open every shard once, in name order.
  std::map<std::string, const WeightFile*> shards;
  for (const auto& [tensor, shard] : wm->items()) {
    if (!shard.is_string())
      throw Error(iname + ": weight_map entry for tensor '" + tensor + "' is not a file name");
    const std::string s = shard.get<std::string>();
    if (s.empty() || s == "." || s == ".." || s.find('/') != std::string::npos || s.find('\\') != std::string::npos)
      throw Error(iname + ": tensor '" + tensor + "' names shard '" + s +
                  "', which is not a plain file name in the index's folder");
    shards.emplace(s, nullptr);
  }
  for (auto& [s, ptr] : shards) {
    std::error_code ec;
    if (!fs::is_regular_file(dir / s, ec))
      throw Error(iname + ": shard '" + s + "' named in weight_map is missing from " + dir.string() +
                  "; the download is incomplete (fetch every shard listed in the index)");
    w.files_.push_back(WeightFile::open(dir / s));
    ptr = w.files_.back().get();
  }

  // Where each tensor physically is: a tensor stored in two shards is ambiguous, whatever the index says.
  std::map<std::string, const WeightFile*, std::less<>> stored;
  for (const auto& f : w.files_)
    for (const WeightEntry* t : f->entries()) {
      const auto [it, fresh] = stored.emplace(t->name, f.get());
      if (!fresh)
        throw Error(iname + ": tensor '" + t->name + "' is present in two shards, " +
                    it->second->path().filename().string() + " and " + f->path().filename().string() +
                    "; the checkpoint is inconsistent");
    }

  uint64_t total = 0;
  for (const auto& [tensor, shard] : wm->items()) {
    const WeightFile* f = shards.at(shard.get<std::string>());
    const WeightEntry* t = f->find(tensor);
    if (!t)
      throw Error(iname + ": tensor '" + tensor + "' is mapped to shard '" + f->path().filename().string() +
                  "', but that shard does not contain it; the index and shards do not match (re-download them)");
    w.entries_.emplace(tensor, WeightRef{f, t});
    total += t->nbytes();
  }
  for (const auto& [name, f] : stored)
    if (!w.entries_.count(name))
      w.warnings_.push_back(iname + ": tensor '" + name + "' in shard " + f->path().filename().string() +
                            " is not listed in weight_map and is ignored");
  if (auto md = j.find("metadata"); md != j.end() && md->is_object())
    if (auto ts = md->find("total_size"); ts != md->end() && ts->is_number_unsigned() && ts->get<uint64_t>() != total)
      w.warnings_.push_back(iname + ": metadata.total_size is " + std::to_string(ts->get<uint64_t>()) +
                            " but the listed tensors hold " + std::to_string(total) + " bytes");
  return w;
}

const WeightRef* WeightSet::find(std::string_view name) const {
  const auto it = entries_.find(name);
  return it == entries_.end() ? nullptr : &it->second;
}

TensorBytes WeightSet::bytes(std::string_view name) const {
  const WeightRef* r = find(name);
  if (!r) throw Error(source_.string() + ": no tensor named '" + std::string(name) + "'");
  return r->file->bytes(*r->info);
}

HostTensor WeightSet::load(std::string_view name) const {
  const WeightRef* r = find(name);
  if (!r) throw Error(source_.string() + ": no tensor named '" + std::string(name) + "'");
  return r->file->load(*r->info);
}

uint64_t WeightSet::total_bytes() const {
  uint64_t n = 0;
  for (const auto& [name, r] : entries_) n += r.info->nbytes();
  return n;
}

}  // namespace dvs
