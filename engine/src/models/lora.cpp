#include "models/lora.hpp"

#include <string_view>
#include <vector>

#include "dvs/error.hpp"
#include "io/model_folder.hpp"

namespace dvs::models {

namespace {

bool ends_with(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

std::map<std::string, LoraAdapter> load_lora(vk::Context& ctx, const std::filesystem::path& file, float scale,
                                             const std::string& prefix) {
  const WeightSet set = WeightSet::open_file(file);
  const std::string where = file.string();
  std::map<std::string, LoraAdapter> out;
  const std::string a_suffix = ".lora_A.weight";
  for (const auto& [name, ref] : set.entries()) {
    if (!ends_with(name, a_suffix)) continue;
    const std::string module = name.substr(0, name.size() - a_suffix.size());
    const std::string b_name = module + ".lora_B.weight";
    if (!set.find(b_name)) throw Error(where + ": '" + name + "' has no matching '" + b_name + "'");
    const HostTensor a = set.load(name);
    const HostTensor b = set.load(b_name);
    if (a.shape.size() != 2 || b.shape.size() != 2 || b.shape[1] != a.shape[0])
      throw Error(where + ": LoRA '" + module + "' has A [" + shape_str(a.shape) + "] and B [" + shape_str(b.shape) +
                  "]; expected A [rank, in] and B [out, rank]");
    const int64_t rank = a.shape[0];
    double s = scale;
    if (set.find(module + ".alpha")) {
      const std::vector<float> v = set.load(module + ".alpha").to_f32();
      if (v.size() != 1) throw Error(where + ": '" + module + ".alpha' must hold one value");
      s *= double(v[0]) / double(rank);
    }
    std::vector<float> up = b.to_f32();
    for (float& x : up) x = float(double(x) * s);
    std::string key = module;
    if (!prefix.empty() && key.rfind(prefix, 0) == 0) key = key.substr(prefix.size());
    LoraAdapter ad;
    ad.rank = rank;
    ad.down = Tensor::upload(ctx, a, "LoRA A " + key);
    ad.up = Tensor::upload(ctx, HostTensor::from_f32(b.shape, up), "LoRA B " + key);
    out.emplace(key, std::move(ad));
  }
  if (out.empty()) throw Error(where + ": no LoRA tensors ('*.lora_A.weight' / '*.lora_B.weight') found");
  return out;
}

}  // namespace dvs::models
