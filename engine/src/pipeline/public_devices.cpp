// dvs/devices.hpp on the Vulkan layer: the device list and limits (vk/device_info), the limit profiles
// (vk/limit_profiles) and DVS_LIMITS (vk/device_limits).
#include <algorithm>

#include "io/public_call.hpp"
#include "dvs/devices.hpp"
#include "dvs/usage_error.hpp"
#include "pipeline/public_limits.hpp"
#include "vk/context.hpp"
#include "vk/device_info.hpp"
#include "vk/device_limits.hpp"
#include "vk/limit_profiles.hpp"

namespace dvs {

DeviceLimits limits_of(const vk::DeviceCaps& d) {
  DeviceLimits l;
  l.source = "device " + std::to_string(d.index) + " (" + d.name + ")";
  l.binding = d.max_storage_buffer_range;
  l.texels = d.max_texel_buffer_elements;
  l.alloc = d.max_memory_allocation_size;
  l.groups = d.max_workgroup_count[0];
  l.alignment = d.min_storage_buffer_offset_alignment;
  l.memory = d.memory_budget.bytes;
  l.transfer_queue = d.transfer_queue_family >= 0 ? 1 : 0;
  return l;
}

std::vector<DeviceSummary> list_devices(const std::string& device_spec) {
  const std::vector<vk::DeviceCaps> devices = vk::list_devices();  // DVS_LIMITS lowers them, as for a run
  const uint32_t chosen = vk::select_device(devices, device_spec);
  std::vector<DeviceSummary> out;
  for (const vk::DeviceCaps& d : devices)
    out.push_back({d.index, d.name, vk::device_type_name(d.type), d.index == chosen, limits_of(d)});
  return out;
}

DeviceLimits device_limits(const std::string& device_spec) {
  const std::vector<vk::DeviceCaps> devices = vk::list_devices();
  return limits_of(devices.at(vk::select_device(devices, device_spec)));
}

DeviceLimits profile_limits(const std::string& profile) {
  return public_call("dvs::profile_limits", [&]() -> DeviceLimits {
    const vk::LimitProfile* found = nullptr;
    try {
      found = &vk::limit_profile(profile);
    } catch (const UsageError&) {
      throw;
    } catch (const Error& e) {
      throw UsageError(e.what());  // a name that is not a profile is the caller's to fix
    }
    const vk::LimitProfile& p = *found;
    DeviceLimits l{"profile " + p.name + " (" + p.describes + ")", p.binding, p.texels, p.alloc, p.groups[0],
                   p.alignment, p.heap, p.upload_bytes_per_second, p.peak_flops, p.transfer_queue ? 1 : 0};
    // DVS_LIMITS lowers a profile as it lowers a device.
    const vk::LimitOverrides env = vk::limit_overrides_from_env();
    if (env.binding) l.binding = std::min(l.binding, *env.binding);
    if (env.texels) l.texels = std::min(l.texels, *env.texels);
    if (env.alloc) l.alloc = std::min(l.alloc, *env.alloc);
    if (env.groups) l.groups = uint32_t(std::min<uint64_t>(l.groups, *env.groups));
    if (env.any()) l.source += " lowered by DVS_LIMITS";
    return l;
  });
}

std::vector<std::string> limit_profile_names() {
  std::vector<std::string> names;
  for (const vk::LimitProfile& p : vk::limit_profiles()) names.push_back(p.name);
  return names;
}

}  // namespace dvs
