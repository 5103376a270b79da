#include "vk/host_device.hpp"

#include <algorithm>

#include "dvs/error.hpp"
#include "vk/device_limits.hpp"

namespace dvs::vk {
namespace {

// VkPhysicalDeviceShaderAtomicFloatFeaturesEXT etc. are reached through their sType; unknown structures are skipped.
template <class T>
const T& as(const VkBaseInStructure* s) {
  return *reinterpret_cast<const T*>(s);
}

bool enabled(const std::vector<std::string>& list, const char* name) {
  return std::find(list.begin(), list.end(), name) != list.end();
}

std::string bullet_list(const std::vector<std::string>& items) {
  std::string out;
  for (const auto& i : items) out += "\n  - " + i;
  return out;
}

}  // namespace

EnabledFeatures enabled_features_in(const void* chain) {
  EnabledFeatures e;
  for (auto* s = static_cast<const VkBaseInStructure*>(chain); s; s = s->pNext) {
    switch (uint32_t(s->sType)) {  // an integer: the coopmat sType may be a macro on older headers
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES:
        e.storage_16bit |= bool(as<VkPhysicalDeviceVulkan11Features>(s).storageBuffer16BitAccess);
        break;
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES: {
        const auto& f = as<VkPhysicalDeviceVulkan12Features>(s);
        e.timeline_semaphore |= bool(f.timelineSemaphore);
        e.storage_8bit |= bool(f.storageBuffer8BitAccess);
        e.float16 |= bool(f.shaderFloat16);
        e.int8 |= bool(f.shaderInt8);
        e.vulkan_memory_model |= bool(f.vulkanMemoryModel);
        e.vulkan_memory_model_device_scope |= bool(f.vulkanMemoryModelDeviceScope);
        break;
      }
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_3_FEATURES: {
        const auto& f = as<VkPhysicalDeviceVulkan13Features>(s);
        e.subgroup_size_control |= bool(f.subgroupSizeControl);
        e.compute_full_subgroups |= bool(f.computeFullSubgroups);
        e.maintenance4 |= bool(f.maintenance4);
        break;
      }
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_TIMELINE_SEMAPHORE_FEATURES:
        e.timeline_semaphore |= bool(as<VkPhysicalDeviceTimelineSemaphoreFeatures>(s).timelineSemaphore);
        break;
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_16BIT_STORAGE_FEATURES:
        e.storage_16bit |= bool(as<VkPhysicalDevice16BitStorageFeatures>(s).storageBuffer16BitAccess);
        break;
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_8BIT_STORAGE_FEATURES:
        e.storage_8bit |= bool(as<VkPhysicalDevice8BitStorageFeatures>(s).storageBuffer8BitAccess);
        break;
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_FLOAT16_INT8_FEATURES: {
        const auto& f = as<VkPhysicalDeviceShaderFloat16Int8Features>(s);
        e.float16 |= bool(f.shaderFloat16);
        e.int8 |= bool(f.shaderInt8);
        break;
      }
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_SIZE_CONTROL_FEATURES: {
        const auto& f = as<VkPhysicalDeviceSubgroupSizeControlFeatures>(s);
        e.subgroup_size_control |= bool(f.subgroupSizeControl);
        e.compute_full_subgroups |= bool(f.computeFullSubgroups);
        break;
      }
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_ATOMIC_FLOAT_FEATURES_EXT:
        e.float32_atomic_add |= bool(as<VkPhysicalDeviceShaderAtomicFloatFeaturesEXT>(s).shaderBufferFloat32AtomicAdd);
        break;
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_COOPERATIVE_MATRIX_FEATURES_KHR:
        e.cooperative_matrix |= bool(as<VkPhysicalDeviceCooperativeMatrixFeaturesKHR>(s).cooperativeMatrix);
        break;
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_COOPERATIVE_MATRIX_2_FEATURES_NV: {
        const auto& f = as<VkPhysicalDeviceCooperativeMatrix2FeaturesNV>(s);
        e.cooperative_matrix2_row_ops |=
            f.cooperativeMatrixReductions && f.cooperativeMatrixConversions && f.cooperativeMatrixPerElementOperations;
        e.cooperative_matrix2_gemm |= f.cooperativeMatrixWorkgroupScope && f.cooperativeMatrixFlexibleDimensions &&
                                      f.cooperativeMatrixTensorAddressing && f.cooperativeMatrixPerElementOperations;
        break;
      }
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_MEMORY_MODEL_FEATURES: {
        const auto& f = as<VkPhysicalDeviceVulkanMemoryModelFeatures>(s);
        e.vulkan_memory_model |= bool(f.vulkanMemoryModel);
        e.vulkan_memory_model_device_scope |= bool(f.vulkanMemoryModelDeviceScope);
        break;
      }
      case VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_4_FEATURES:
        e.maintenance4 |= bool(as<VkPhysicalDeviceMaintenance4Features>(s).maintenance4);
        break;
      default:
        break;
    }
  }
  return e;
}

std::vector<std::string> host_device_requirements() {
  return {"Vulkan 1.2 (instance apiVersion and device)", "timelineSemaphore",
          "a queue family with VK_QUEUE_COMPUTE_BIT",
          "vulkanMemoryModelDeviceScope (only where vulkanMemoryModel is enabled)"};
}

std::vector<std::string> host_device_options() {
  return {"shaderFloat16 (attention kernels in fp16)",
          "shaderBufferFloat32AtomicAdd with VK_EXT_shader_atomic_float (the splat render's float path)",
          "cooperativeMatrix with VK_KHR_cooperative_matrix, vulkanMemoryModel and maintenance4 on Vulkan 1.3 "
          "(tensor-core GEMM, convolution and attention)",
          "cooperativeMatrixReductions, cooperativeMatrixConversions and cooperativeMatrixPerElementOperations with "
          "VK_NV_cooperative_matrix2 (the tensor-core attention's softmax in registers)",
          "cooperativeMatrixWorkgroupScope, cooperativeMatrixFlexibleDimensions, cooperativeMatrixTensorAddressing and "
          "cooperativeMatrixPerElementOperations with VK_NV_cooperative_matrix2 (the coopmat2 GEMM, where the tuning "
          "asks for it)",
          "subgroupSizeControl and computeFullSubgroups (Vulkan 1.3 or VK_EXT_subgroup_size_control)",
          "storageBuffer16BitAccess, storageBuffer8BitAccess, shaderInt8",
          "VK_EXT_memory_budget (the memory budget follows the driver's heap budgets)"};
}

DeviceCaps host_device_caps(const HostDevice& host) {
  std::vector<std::string> missing;
  if (!host.instance) missing.push_back("HostDevice::instance is VK_NULL_HANDLE: pass the application's VkInstance");
  if (!host.physical_device)
    missing.push_back("HostDevice::physical_device is VK_NULL_HANDLE: pass the VkPhysicalDevice the device was made on");
  if (!host.device) missing.push_back("HostDevice::device is VK_NULL_HANDLE: pass the application's VkDevice");
  if (!host.queue) missing.push_back("HostDevice::queue is VK_NULL_HANDLE: pass a VkQueue of HostDevice::queue_family");
  if (!host.physical_device)
    throw Error("dvs cannot use the application's Vulkan device:" + bullet_list(missing));

  DeviceCaps c = query_device_caps(host.physical_device, 0, host.instance);
  // What the application can use is the lower of the instance's and the device's versions.
  const uint32_t device_api = c.api_version;
  c.api_version = std::min(c.api_version, host.instance_api_version);
  if (host.instance_api_version < VK_API_VERSION_1_2)
    missing.push_back("Vulkan 1.2: HostDevice::instance_api_version is " + version_string(host.instance_api_version) +
                      "; create the VkInstance with VkApplicationInfo::apiVersion = VK_API_VERSION_1_2 (or later) "
                      "and pass that value");
  if (device_api < VK_API_VERSION_1_2)
    missing.push_back("Vulkan 1.2: device '" + c.name + "' supports only Vulkan " + version_string(device_api) +
                      "; use a device or driver with Vulkan 1.2");

  uint32_t nq = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(host.physical_device, &nq, nullptr);
  std::vector<VkQueueFamilyProperties> families(nq);
  vkGetPhysicalDeviceQueueFamilyProperties(host.physical_device, &nq, families.data());
  if (host.queue_family >= nq) {
    missing.push_back("VK_QUEUE_COMPUTE_BIT: HostDevice::queue_family is " + std::to_string(host.queue_family) +
                      " but the device has " + std::to_string(nq) + " queue families");
  } else if (!(families[host.queue_family].queueFlags & VK_QUEUE_COMPUTE_BIT)) {
    missing.push_back("VK_QUEUE_COMPUTE_BIT: queue family " + std::to_string(host.queue_family) +
                      " has no compute; pass a queue of a family with VK_QUEUE_COMPUTE_BIT"
                      " (family " + std::to_string(c.queue_family) + " has it)");
  } else {
    const auto& family = families[host.queue_family];
    c.queue_family = host.queue_family;
    c.queue_compute_only = !(family.queueFlags & VK_QUEUE_GRAPHICS_BIT);
    c.has_compute_queue = true;
    VkPhysicalDeviceProperties props{};
    vkGetPhysicalDeviceProperties(host.physical_device, &props);
    c.timestamps = props.limits.timestampComputeAndGraphics && family.timestampValidBits > 0;
  }

  const EnabledFeatures e = enabled_features_in(host.enabled_features);
  if (!e.timeline_semaphore)
    missing.push_back(std::string("timelineSemaphore: create the VkDevice with "
                                  "VkPhysicalDeviceVulkan12Features::timelineSemaphore = VK_TRUE") +
                      (host.enabled_features ? "" : " and pass that feature chain in HostDevice::enabled_features"));
  // With the Vulkan memory model on, shaders with Device-scope atomics (dvs's cast and non-finite checks) also
  // need vulkanMemoryModelDeviceScope (VUID-RuntimeSpirv-vulkanMemoryModel-06265).
  if (e.vulkan_memory_model && !e.vulkan_memory_model_device_scope)
    missing.push_back("vulkanMemoryModelDeviceScope: the device was created with vulkanMemoryModel, so dvs's "
                      "shaders with device-scope atomics need VkPhysicalDeviceVulkan12Features::"
                      "vulkanMemoryModelDeviceScope = VK_TRUE too (or create the device without vulkanMemoryModel)");
  if (!missing.empty())
    throw Error("dvs cannot use the application's Vulkan device '" + c.name + "'; missing:" + bullet_list(missing));

  // Only what the application enabled (features and their extensions).
  const auto& exts = host.enabled_extensions;
  const bool v13 = c.api_version >= VK_API_VERSION_1_3;
  c.storage_16bit = c.storage_16bit && e.storage_16bit;
  c.storage_8bit = c.storage_8bit && e.storage_8bit;
  c.float16_arithmetic = c.float16_arithmetic && e.float16;
  c.int8_arithmetic = c.int8_arithmetic && e.int8;
  c.subgroup_size_control = c.subgroup_size_control && e.subgroup_size_control && e.compute_full_subgroups &&
                            (v13 || enabled(exts, "VK_EXT_subgroup_size_control"));
  c.float32_atomic_add = c.float32_atomic_add && e.float32_atomic_add && enabled(exts, "VK_EXT_shader_atomic_float");
  c.vulkan_memory_model = c.vulkan_memory_model && e.vulkan_memory_model;
  c.cooperative_matrix = c.cooperative_matrix && v13 && e.cooperative_matrix && e.vulkan_memory_model &&
                         e.maintenance4 && enabled(exts, VK_KHR_COOPERATIVE_MATRIX_EXTENSION_NAME);
  if (!c.cooperative_matrix) c.cooperative_matrix_shapes.clear();
  c.cooperative_matrix2_row_ops = c.cooperative_matrix2_row_ops && c.cooperative_matrix && e.cooperative_matrix2_row_ops &&
                                  enabled(exts, VK_NV_COOPERATIVE_MATRIX_2_EXTENSION_NAME);
  c.cooperative_matrix2_gemm = c.cooperative_matrix2_gemm && c.cooperative_matrix && c.storage_16bit &&
                               c.float16_arithmetic && e.cooperative_matrix2_gemm &&
                               enabled(exts, VK_NV_COOPERATIVE_MATRIX_2_EXTENSION_NAME);
  c.push_descriptor = c.push_descriptor && enabled(exts, "VK_KHR_push_descriptor");
  if (c.memory_budget_ext && !enabled(exts, VK_EXT_MEMORY_BUDGET_EXTENSION_NAME)) {
    c.memory_budget_ext = false;
    c.memory_budget = query_memory_budget(host.physical_device, c.type, false);
    apply_limit_overrides(c, limit_overrides_from_env());  // DVS_LIMITS memory= lowers the budget read again
  }
  return c;
}

}  // namespace dvs::vk
