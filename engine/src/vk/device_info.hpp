// What a physical device offers that dvs cares about: identity, the optional features it can use, the
// limits that shape memory and kernels, and its memory heaps. Filled by query_device_caps().
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "vk/cooperative_matrix2.hpp"
#include "vk/cooperative_matrix_khr.hpp"
#include "vk/memory_budget.hpp"

namespace dvs::vk {

struct MemoryHeapInfo {
  uint64_t size = 0;
  bool device_local = false;
  bool host_visible = false;  // some memory type of this heap is host-visible
};

// The device's own values of the limits DVS_LIMITS can lower (device_limits.hpp).
struct DeviceLimitValues {
  uint64_t binding = 0, texels = 0, alloc = 0, memory = 0;
  uint32_t groups[3] = {};
};
struct ForcedLimits {
  bool binding = false, texels = false, alloc = false, groups = false, memory = false;
  bool any() const { return binding || texels || alloc || groups || memory; }
};

// One entry of vkGetPhysicalDeviceCooperativeMatrixPropertiesKHR: C/Result = A·B + C with A MxK, B KxN.
struct CooperativeMatrixShape {
  uint32_t m = 0, n = 0, k = 0;
  VkComponentTypeKHR a = VK_COMPONENT_TYPE_FLOAT16_KHR, b = VK_COMPONENT_TYPE_FLOAT16_KHR,
                     c = VK_COMPONENT_TYPE_FLOAT32_KHR, result = VK_COMPONENT_TYPE_FLOAT32_KHR;
  bool saturating = false;
  VkScopeKHR scope = VK_SCOPE_SUBGROUP_KHR;
};
const char* component_type_name(VkComponentTypeKHR t);
// "f16*f16+f32->f32": a shape's A, B, C and result types, as `dvs info` prints them.
std::string cooperative_matrix_types_text(VkComponentTypeKHR a, VkComponentTypeKHR b, VkComponentTypeKHR c,
                                          VkComponentTypeKHR result);
const char* scope_name(VkScopeKHR s);  // "subgroup", "workgroup", "other-scope"

struct DeviceCaps {
  uint32_t index = 0;
  std::string name;
  VkPhysicalDeviceType type = VK_PHYSICAL_DEVICE_TYPE_OTHER;
  std::string driver_name, driver_info;
  uint32_t api_version = 0, driver_version = 0, vendor_id = 0, device_id = 0;
  uint8_t pipeline_cache_uuid[VK_UUID_SIZE] = {};

  uint32_t subgroup_size = 0;
  uint32_t min_subgroup_size = 0, max_subgroup_size = 0;  // 0 when size control is absent
  // Size control's limits for compute: subgroups per workgroup at most (0 when absent), and whether a compute
  // pipeline may require a subgroup size (requiredSubgroupSizeStages has compute; the tensor-core kernels do).
  uint32_t max_compute_workgroup_subgroups = 0;
  bool compute_required_subgroup_size = false;
  bool subgroup_arithmetic = false, subgroup_shuffle = false, subgroup_size_control = false;
  bool storage_16bit = false, storage_8bit = false;
  bool float16_arithmetic = false, int8_arithmetic = false;
  bool float32_atomic_add = false;   // VK_EXT_shader_atomic_float, buffer add
  bool cooperative_matrix = false;   // VK_KHR_cooperative_matrix with its cooperativeMatrix feature
  std::vector<CooperativeMatrixShape> cooperative_matrix_shapes;  // what the device offers (empty without)
  bool cooperative_matrix2 = false;  // VK_NV_cooperative_matrix2 exposed
  // Its reductions, conversions and per-element operations, usable (with cooperative_matrix): enabled on the
  // device dvs creates; the application's must have enabled them. The attention kernel's softmax uses them
  // (nn/attention_flash_coopmat2).
  bool cooperative_matrix2_row_ops = false;
  // Its workgroup-scope matrices with flexible dimensions, tensor addressing and per-element operations, usable
  // (with cooperative_matrix): enabled on the device dvs creates; the application's must have enabled them. The GEMM
  // kernel linalg/linear_coopmat2 uses them (DeviceTuning::linear_coopmat2).
  bool cooperative_matrix2_gemm = false;
  std::optional<CooperativeMatrix2Facts> cooperative_matrix2_facts;  // its features, limits, flexible shapes
  bool vulkan_memory_model = false;  // Vulkan 1.2 vulkanMemoryModel (the coopmat shaders' memory model)
  bool push_descriptor = false;
  // VK_KHR_pipeline_executable_properties with pipelineExecutableInfo: a pipeline's compiled code can report its
  // statistics (registers, spills, ...; vk/pipeline_statistics.hpp). NVIDIA has it; lavapipe does not.
  bool pipeline_executable_info = false;

  // The limits every op and allocation honours: the device's, lowered by DVS_LIMITS where it says so
  // (device_limits holds the device's own values, forced_limits which were lowered).
  uint64_t max_storage_buffer_range = 0;
  uint64_t max_memory_allocation_size = 0;
  uint64_t min_storage_buffer_offset_alignment = 0;
  uint64_t min_texel_buffer_offset_alignment = 0;
  uint64_t max_texel_buffer_elements = 0;
  uint32_t max_compute_shared_memory = 0;
  uint32_t max_workgroup_invocations = 0;
  uint32_t max_workgroup_count[3] = {};
  DeviceLimitValues device_limits;
  ForcedLimits forced_limits;
  uint32_t max_push_constants = 0;
  float timestamp_period_ns = 0;
  bool timestamps = false;

  // The queue family dvs submits to (pick_compute_queue_family); compute_only: it has no graphics.
  uint32_t queue_family = 0;
  bool queue_compute_only = false;
  bool has_compute_queue = false;
  int transfer_queue_family = -1;  // pick_transfer_queue_family (-1: none; uploads then go on the compute queue)

  std::vector<MemoryHeapInfo> heaps;
  DeviceMemoryBudget memory_budget;  // what dvs may hold (memory_budget.hpp: host RAM on CPU devices)
  bool memory_budget_ext = false;    // VK_EXT_memory_budget
  std::vector<std::string> extensions;

  bool has_extension(const char* name) const;
};

const char* device_type_name(VkPhysicalDeviceType t);
std::string version_string(uint32_t v);

// `instance` resolves the extension queries (cooperative-matrix shapes); VK_NULL_HANDLE skips them.
DeviceCaps query_device_caps(VkPhysicalDevice pd, uint32_t index, VkInstance instance = VK_NULL_HANDLE);

// A family with COMPUTE but not GRAPHICS where the device has one (NVIDIA/AMD: an async compute queue that a
// desktop's graphics work does not share), else the first with COMPUTE; -1 when none has COMPUTE.
int pick_compute_queue_family(const std::vector<VkQueueFamilyProperties>& families);
// A family with TRANSFER but neither GRAPHICS nor COMPUTE (a GPU's copy engine: NVIDIA's and AMD's DMA queues);
// -1 when there is none (lavapipe, most integrated GPUs).
int pick_transfer_queue_family(const std::vector<VkQueueFamilyProperties>& families);

// Picks a device: `spec` is an index ("0") or a case-insensitive name substring ("llvmpipe"); empty means
// the DVS_DEVICE environment variable, else the first discrete GPU, else integrated, else anything.
// Throws dvs::Error listing the devices when nothing matches.
uint32_t select_device(const std::vector<DeviceCaps>& devices, const std::string& spec);

// Human-readable report of one device, as `dvs info` prints it.
std::string describe_device(const DeviceCaps& caps);

}  // namespace dvs::vk
