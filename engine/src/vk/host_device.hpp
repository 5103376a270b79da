// An application's Vulkan device as dvs sees it (dvs::HostDevice, dvs/context.hpp): what the application enabled
// when it created the device, and the device's capabilities limited to that. dvs cannot read the enabled features
// back from a VkDevice, so it uses a feature only where the application's feature chain says it is on; every
// DeviceCaps flag of a feature that is off is cleared, and no kernel then picks a shader that needs it.
#pragma once
#include <vulkan/vulkan.h>

#include <string>
#include <vector>

#include "dvs/context.hpp"
#include "vk/device_info.hpp"

namespace dvs::vk {

// The features dvs cares about, as enabled in a VkDeviceCreateInfo::pNext chain.
struct EnabledFeatures {
  bool timeline_semaphore = false;
  bool storage_16bit = false, storage_8bit = false;
  bool float16 = false, int8 = false;
  bool subgroup_size_control = false, compute_full_subgroups = false;
  bool float32_atomic_add = false;
  bool cooperative_matrix = false;
  bool cooperative_matrix2_row_ops = false;  // VK_NV_cooperative_matrix2's reductions, conversions, per-element ops
  bool cooperative_matrix2_gemm = false;  // its workgroup scope, flexible dimensions, tensor addressing, per-element ops
  bool vulkan_memory_model = false, vulkan_memory_model_device_scope = false;
  bool maintenance4 = false;
};

// Reads a feature chain (VkPhysicalDeviceFeatures2, VkPhysicalDeviceVulkan11/12/13Features or the individual
// feature structures, in any order); nullptr: nothing enabled.
EnabledFeatures enabled_features_in(const void* chain);

// What a HostDevice must offer and what dvs uses when it is enabled, by their Vulkan names.
std::vector<std::string> host_device_requirements();
std::vector<std::string> host_device_options();

// The capabilities dvs works with on the application's device: query_device_caps with the queue family the
// application gave and the flags of what it did not enable cleared. Throws dvs::Error naming every requirement the
// device or the HostDevice misses, each with what to do.
DeviceCaps host_device_caps(const HostDevice& host);

}  // namespace dvs::vk
