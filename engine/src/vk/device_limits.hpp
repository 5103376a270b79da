// The four device limits every op and allocation is planned against, and DVS_LIMITS: a way to lower them
// below the device's so that tests at tiny sizes take the split paths real sizes need.
//
//   DVS_LIMITS=binding=64KiB,texels=16384,alloc=1MiB,groups=4096,memory=256MiB
//
// binding: maxStorageBufferRange (bytes one storage-buffer descriptor covers); texels:
// maxTexelBufferElements (texels one texel-buffer view holds); alloc: maxMemoryAllocationSize (bytes of one
// VkDeviceMemory); groups: maxComputeWorkGroupCount (each of x, y, z); memory: the device memory dvs may hold
// (its budget: the run plans against it and the allocator refuses beyond it). Any subset, comma-separated; values
// are integers with an optional binary unit (KiB, MiB, GiB: ×1024, ×1024², ×1024³). A value above the
// device's keeps the device's. Anything malformed is a UsageError naming the variable and the item.
#pragma once
#include <cstdint>
#include <optional>
#include <string>

namespace dvs::vk {

struct DeviceCaps;

struct LimitOverrides {
  std::optional<uint64_t> binding, texels, alloc, groups, memory;
  bool any() const { return binding || texels || alloc || groups || memory; }
};

// Parses a DVS_LIMITS value ("" gives no overrides). `source` names it in errors.
LimitOverrides parse_limit_overrides(const std::string& spec, const std::string& source = "DVS_LIMITS");
// The DVS_LIMITS environment variable, parsed (no overrides when unset or empty).
LimitOverrides limit_overrides_from_env();

// The device's own values, kept in caps.device_limits, then lowered in place where an override is lower
// (caps.max_storage_buffer_range etc. are what every op plans against; memory lowers caps.memory_budget.bytes,
// so it applies after the budget is known); caps.forced_limits says which were.
void apply_limit_overrides(DeviceCaps& caps, const LimitOverrides& overrides);

// Bytes per texel of the formats dvs binds as texel buffers (0 for any other format).
uint32_t texel_format_bytes(int vk_format);

}  // namespace dvs::vk
