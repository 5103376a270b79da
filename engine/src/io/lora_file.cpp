#include "io/lora_file.hpp"

#include <cmath>
#include <string_view>
#include <vector>

#include "dvs/error.hpp"
#include "io/option_names.hpp"
#include "io/weight_set.hpp"

namespace dvs {
namespace {

bool ends_with(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

std::map<std::string, LoraFileAdapter> read_lora_file(const std::filesystem::path& file, double user_scale,
                                                      const std::string& prefix) {
  const WeightSet set = WeightSet::open_file(file);
  const std::string where = file.string();
  const std::string a_suffix = ".lora_A.weight";
  std::map<std::string, LoraFileAdapter> out;
  for (const auto& [name, ref] : set.entries()) {
    if (!ends_with(name, a_suffix)) continue;
    const std::string module = name.substr(0, name.size() - a_suffix.size());
    const std::string b_name = module + ".lora_B.weight";
    if (!set.find(b_name)) throw Error(where + ": '" + name + "' has no matching '" + b_name + "'");
    LoraFileAdapter ad;
    ad.a = set.load(name);
    ad.b = set.load(b_name);
    if (ad.a.shape.size() != 2 || ad.b.shape.size() != 2 || ad.b.shape[1] != ad.a.shape[0])
      throw Error(where + ": LoRA '" + module + "' has A [" + shape_str(ad.a.shape) + "] and B [" + shape_str(ad.b.shape) +
                  "]; expected A [rank, in] and B [out, rank]");
    ad.scale = user_scale;
    if (set.find(module + ".alpha")) {
      const std::vector<float> v = set.load(module + ".alpha").to_f32();
      if (v.size() != 1) throw Error(where + ": '" + module + ".alpha' must hold one value");
      ad.scale *= double(v[0]) / double(ad.rank());
    }
    std::string key = module;
    if (!prefix.empty() && key.rfind(prefix, 0) == 0) key = key.substr(prefix.size());
    out.emplace(key, std::move(ad));
  }
  if (out.empty()) throw Error(where + ": no LoRA tensors ('*.lora_A.weight' / '*.lora_B.weight') found");
  return out;
}

LoraSpec parse_lora_spec(const std::string& spec) {
  std::error_code ec;
  const size_t colon = spec.rfind(':');
  if (std::filesystem::exists(spec, ec) || colon == std::string::npos) return {spec, 1.0};
  const std::string tail = spec.substr(colon + 1);
  try {
    size_t used = 0;
    const double scale = std::stod(tail, &used);
    if (used == tail.size() && std::isfinite(scale)) return {spec.substr(0, colon), scale};
  } catch (const std::logic_error&) {
  }
  throw Error(option_name("RunOptions::lora") + " " + spec + ": the scale after ':' must be a number, got '" + tail + "'");
}

}  // namespace dvs
