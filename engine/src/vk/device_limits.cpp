#include "vk/device_limits.hpp"

#include <vulkan/vulkan.h>

#include <algorithm>
#include <cstdlib>
#include <limits>

#include "dvs/usage_error.hpp"
#include "vk/device_info.hpp"

namespace dvs::vk {
namespace {

std::string trim(const std::string& s) {
  size_t a = s.find_first_not_of(" \t"), b = s.find_last_not_of(" \t");
  return a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
}

uint64_t parse_value(const std::string& item, const std::string& text, const std::string& source) {
  auto bad = [&](const std::string& why) {
    return UsageError(source + ": '" + item + "': " + why +
                      ". Expected KEY=VALUE items separated by commas, KEY one of binding, texels, alloc, groups, memory, "
                      "VALUE a positive integer with an optional unit KiB, MiB or GiB (e.g. binding=64KiB).");
  };
  size_t digits = 0;
  while (digits < text.size() && text[digits] >= '0' && text[digits] <= '9') ++digits;
  if (digits == 0) throw bad("the value does not start with a number");
  if (digits > 15) throw bad("the value is too large");
  uint64_t v = std::stoull(text.substr(0, digits));
  const std::string unit = trim(text.substr(digits));
  uint64_t mul = 1;
  if (unit == "KiB") mul = 1ull << 10;
  else if (unit == "MiB") mul = 1ull << 20;
  else if (unit == "GiB") mul = 1ull << 30;
  else if (!unit.empty()) throw bad("unknown unit '" + unit + "' (binary units only: KiB, MiB, GiB)");
  if (v == 0) throw bad("the value must be positive");
  return v * mul;
}

}  // namespace

LimitOverrides parse_limit_overrides(const std::string& spec, const std::string& source) {
  LimitOverrides o;
  size_t pos = 0;
  while (pos <= spec.size()) {
    size_t end = spec.find(',', pos);
    if (end == std::string::npos) end = spec.size();
    const std::string item = trim(spec.substr(pos, end - pos));
    pos = end + 1;
    if (item.empty()) {
      if (end == spec.size()) break;
      throw UsageError(source + ": an empty item in '" + spec + "'");
    }
    const size_t eq = item.find('=');
    if (eq == std::string::npos)
      throw UsageError(source + ": '" + item + "' is not KEY=VALUE (keys: binding, texels, alloc, groups, memory)");
    const std::string key = trim(item.substr(0, eq));
    const uint64_t v = parse_value(item, trim(item.substr(eq + 1)), source);
    std::optional<uint64_t>* slot = key == "binding" ? &o.binding
                                    : key == "texels" ? &o.texels
                                    : key == "alloc"  ? &o.alloc
                                    : key == "groups" ? &o.groups
                                    : key == "memory" ? &o.memory
                                                      : nullptr;
    if (!slot)
      throw UsageError(source + ": unknown key '" + key + "' in '" + item + "' (keys: binding, texels, alloc, groups, memory)");
    if (*slot) throw UsageError(source + ": '" + key + "' is given twice");
    *slot = v;
  }
  // Below these nothing can run (one aligned row of a tiny model, one workgroup grid row).
  if (o.binding && *o.binding < 1024) throw UsageError(source + ": binding must be at least 1KiB");
  if (o.binding && *o.binding % 4) throw UsageError(source + ": binding must be a multiple of 4 bytes");
  if (o.texels && *o.texels < 256) throw UsageError(source + ": texels must be at least 256");
  if (o.alloc && *o.alloc < 64 * 1024) throw UsageError(source + ": alloc must be at least 64KiB");
  if (o.groups && *o.groups < 64) throw UsageError(source + ": groups must be at least 64");
  if (o.groups && *o.groups > std::numeric_limits<uint32_t>::max()) throw UsageError(source + ": groups is too large");
  if (o.memory && *o.memory < 1024 * 1024) throw UsageError(source + ": memory must be at least 1MiB");
  return o;
}

LimitOverrides limit_overrides_from_env() {
  const char* e = std::getenv("DVS_LIMITS");
  return e ? parse_limit_overrides(e) : LimitOverrides{};
}

void apply_limit_overrides(DeviceCaps& c, const LimitOverrides& o) {
  DeviceLimitValues& d = c.device_limits;
  d.binding = c.max_storage_buffer_range;
  d.texels = c.max_texel_buffer_elements;
  d.alloc = c.max_memory_allocation_size;
  for (int i = 0; i < 3; ++i) d.groups[i] = c.max_workgroup_count[i];
  d.memory = c.memory_budget.bytes;
  c.forced_limits = {};
  if (o.binding && *o.binding < c.max_storage_buffer_range) {
    c.max_storage_buffer_range = *o.binding;
    c.forced_limits.binding = true;
  }
  if (o.texels && *o.texels < c.max_texel_buffer_elements) {
    c.max_texel_buffer_elements = *o.texels;
    c.forced_limits.texels = true;
  }
  if (o.alloc && *o.alloc < c.max_memory_allocation_size) {
    c.max_memory_allocation_size = *o.alloc;
    c.forced_limits.alloc = true;
  }
  if (o.memory && *o.memory < c.memory_budget.bytes) {
    c.memory_budget.bytes = *o.memory;
    c.forced_limits.memory = true;
  }
  if (o.groups)
    for (int i = 0; i < 3; ++i)
      if (*o.groups < c.max_workgroup_count[i]) {
        c.max_workgroup_count[i] = uint32_t(*o.groups);
        c.forced_limits.groups = true;
      }
}

uint32_t texel_format_bytes(int vk_format) {
  switch (VkFormat(vk_format)) {
    case VK_FORMAT_R16_UINT: return 2;
    case VK_FORMAT_R32_SFLOAT:
    case VK_FORMAT_R32_UINT: return 4;
    case VK_FORMAT_R32G32B32A32_SFLOAT:
    case VK_FORMAT_R32G32B32A32_UINT: return 16;
    default: return 0;
  }
}

}  // namespace dvs::vk
