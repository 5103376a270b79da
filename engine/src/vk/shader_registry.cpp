#include "vk/shader_registry.hpp"

#include "dvs/error.hpp"

namespace dvs::vk::embedded {
struct Entry {
  const char* name;
  const uint32_t* words;
  size_t count;
};
extern const Entry kShaders[];
}  // namespace dvs::vk::embedded

namespace dvs::vk {

std::span<const uint32_t> find_shader(const std::string& name) {
  for (const embedded::Entry* e = embedded::kShaders; e->name; ++e)
    if (name == e->name) return {e->words, e->count};
  throw Error("internal: no shader named '" + name + "' is embedded in this build");
}

std::vector<std::string> shader_names() {
  std::vector<std::string> out;
  for (const embedded::Entry* e = embedded::kShaders; e->name; ++e) out.emplace_back(e->name);
  return out;
}

uint64_t shaders_hash() {
  static const uint64_t hash = [] {
    uint64_t h = 1469598103934665603ull;  // FNV-1a over names and words
    auto mix = [&h](uint64_t v) {
      h ^= v;
      h *= 1099511628211ull;
    };
    for (const embedded::Entry* e = embedded::kShaders; e->name; ++e) {
      for (const char* c = e->name; *c; ++c) mix(uint8_t(*c));
      for (size_t i = 0; i < e->count; ++i) mix(e->words[i]);
    }
    return h;
  }();
  return hash;
}

}  // namespace dvs::vk
