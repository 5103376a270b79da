#include "vk/device_info.hpp"

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include "dvs/error.hpp"
#include "vk/device_limits.hpp"
#include "vk/memory.hpp"

namespace dvs::vk {

bool DeviceCaps::has_extension(const char* n) const {
  return std::find(extensions.begin(), extensions.end(), n) != extensions.end();
}

const char* device_type_name(VkPhysicalDeviceType t) {
  switch (t) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU: return "discrete GPU";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU: return "integrated GPU";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU: return "virtual GPU";
    case VK_PHYSICAL_DEVICE_TYPE_CPU: return "CPU";
    default: return "other";
  }
}

std::string version_string(uint32_t v) {
  return std::to_string(VK_API_VERSION_MAJOR(v)) + "." + std::to_string(VK_API_VERSION_MINOR(v)) + "." +
         std::to_string(VK_API_VERSION_PATCH(v));
}

std::string cooperative_matrix_types_text(VkComponentTypeKHR a, VkComponentTypeKHR b, VkComponentTypeKHR c,
                                          VkComponentTypeKHR result) {
  return std::string(component_type_name(a)) + "*" + component_type_name(b) + "+" + component_type_name(c) + "->" +
         component_type_name(result);
}

const char* scope_name(VkScopeKHR s) {
  return s == VK_SCOPE_SUBGROUP_KHR ? "subgroup" : s == VK_SCOPE_WORKGROUP_KHR ? "workgroup" : "other-scope";
}

const char* component_type_name(VkComponentTypeKHR t) {
  switch (t) {
    case VK_COMPONENT_TYPE_FLOAT16_KHR: return "f16";
    case VK_COMPONENT_TYPE_FLOAT32_KHR: return "f32";
    case VK_COMPONENT_TYPE_FLOAT64_KHR: return "f64";
    case VK_COMPONENT_TYPE_SINT8_KHR: return "s8";
    case VK_COMPONENT_TYPE_SINT16_KHR: return "s16";
    case VK_COMPONENT_TYPE_SINT32_KHR: return "s32";
    case VK_COMPONENT_TYPE_SINT64_KHR: return "s64";
    case VK_COMPONENT_TYPE_UINT8_KHR: return "u8";
    case VK_COMPONENT_TYPE_UINT16_KHR: return "u16";
    case VK_COMPONENT_TYPE_UINT32_KHR: return "u32";
    case VK_COMPONENT_TYPE_UINT64_KHR: return "u64";
    default: break;
  }
  switch (int(t)) {  // values newer headers name (bfloat16, fp8)
    case 1000141000: return "bf16";
    case 1000491002: return "e4m3";
    case 1000491003: return "e5m2";
    default: return "other";
  }
}

DeviceCaps query_device_caps(VkPhysicalDevice pd, uint32_t index, VkInstance instance) {
  DeviceCaps c;
  c.index = index;

  uint32_t n_ext = 0;
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &n_ext, nullptr);
  std::vector<VkExtensionProperties> exts(n_ext);
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &n_ext, exts.data());
  for (auto& e : exts) c.extensions.emplace_back(e.extensionName);

  VkPhysicalDeviceProperties base{};
  vkGetPhysicalDeviceProperties(pd, &base);
  c.api_version = base.apiVersion;

  // Properties chain (Vulkan 1.1+ core structures).
  VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
  VkPhysicalDeviceSubgroupProperties subgroup{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
  VkPhysicalDeviceSubgroupSizeControlProperties sgctl{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_SIZE_CONTROL_PROPERTIES};
  VkPhysicalDeviceMaintenance3Properties maint3{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_3_PROPERTIES};
  VkPhysicalDeviceProperties2 props{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props.pNext = &driver;
  driver.pNext = &subgroup;
  subgroup.pNext = &maint3;
  bool has_sgctl = c.api_version >= VK_API_VERSION_1_3 || c.has_extension("VK_EXT_subgroup_size_control");
  if (has_sgctl) maint3.pNext = &sgctl;
  vkGetPhysicalDeviceProperties2(pd, &props);

  c.name = base.deviceName;
  c.type = base.deviceType;
  c.driver_version = base.driverVersion;
  c.vendor_id = base.vendorID;
  c.device_id = base.deviceID;
  std::memcpy(c.pipeline_cache_uuid, base.pipelineCacheUUID, VK_UUID_SIZE);
  c.driver_name = driver.driverName;
  c.driver_info = driver.driverInfo;
  c.subgroup_size = subgroup.subgroupSize;
  c.subgroup_arithmetic = subgroup.supportedOperations & VK_SUBGROUP_FEATURE_ARITHMETIC_BIT;
  c.subgroup_shuffle = subgroup.supportedOperations & VK_SUBGROUP_FEATURE_SHUFFLE_BIT;
  if (has_sgctl) {
    c.min_subgroup_size = sgctl.minSubgroupSize;
    c.max_subgroup_size = sgctl.maxSubgroupSize;
    c.max_compute_workgroup_subgroups = sgctl.maxComputeWorkgroupSubgroups;
    c.compute_required_subgroup_size = sgctl.requiredSubgroupSizeStages & VK_SHADER_STAGE_COMPUTE_BIT;
  }
  const VkPhysicalDeviceLimits& L = base.limits;
  c.max_storage_buffer_range = L.maxStorageBufferRange;
  c.max_memory_allocation_size = maint3.maxMemoryAllocationSize;
  c.min_storage_buffer_offset_alignment = L.minStorageBufferOffsetAlignment;
  c.min_texel_buffer_offset_alignment = L.minTexelBufferOffsetAlignment;
  c.max_texel_buffer_elements = L.maxTexelBufferElements;
  c.max_compute_shared_memory = L.maxComputeSharedMemorySize;
  c.max_workgroup_invocations = L.maxComputeWorkGroupInvocations;
  for (int i = 0; i < 3; ++i) c.max_workgroup_count[i] = L.maxComputeWorkGroupCount[i];
  c.max_push_constants = L.maxPushConstantsSize;
  c.timestamp_period_ns = L.timestampPeriod;
  c.timestamps = L.timestampComputeAndGraphics;
  {
    uint32_t nq = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(pd, &nq, nullptr);
    std::vector<VkQueueFamilyProperties> qf(nq);
    vkGetPhysicalDeviceQueueFamilyProperties(pd, &nq, qf.data());
    const int q = pick_compute_queue_family(qf);
    c.has_compute_queue = q >= 0;
    if (q >= 0) {
      c.queue_family = uint32_t(q);
      c.queue_compute_only = !(qf[size_t(q)].queueFlags & VK_QUEUE_GRAPHICS_BIT);
      if (qf[size_t(q)].timestampValidBits == 0) c.timestamps = false;
    }
    c.transfer_queue_family = pick_transfer_queue_family(qf);
  }

  // Features chain.
  VkPhysicalDeviceVulkan11Features f11{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES};
  VkPhysicalDeviceVulkan12Features f12{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_2_FEATURES};
  VkPhysicalDeviceSubgroupSizeControlFeatures fsg{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_SIZE_CONTROL_FEATURES};
  VkPhysicalDeviceShaderAtomicFloatFeaturesEXT fat{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SHADER_ATOMIC_FLOAT_FEATURES_EXT};
  VkPhysicalDeviceCooperativeMatrixFeaturesKHR fcm{};
  fcm.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_COOPERATIVE_MATRIX_FEATURES_KHR;
  VkPhysicalDeviceFeatures2 feats{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  feats.pNext = &f11;
  f11.pNext = &f12;
  void** tail = &f12.pNext;
  if (has_sgctl) { *tail = &fsg; tail = &fsg.pNext; }
  const bool has_coopmat = c.has_extension(VK_KHR_COOPERATIVE_MATRIX_EXTENSION_NAME);
  if (has_coopmat) { *tail = &fcm; tail = &fcm.pNext; }
  bool has_atomic_float = c.has_extension("VK_EXT_shader_atomic_float");
  if (has_atomic_float) { *tail = &fat; tail = &fat.pNext; }
  VkPhysicalDevicePipelineExecutablePropertiesFeaturesKHR fpe{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PIPELINE_EXECUTABLE_PROPERTIES_FEATURES_KHR};
  const bool has_executable_properties = c.has_extension(VK_KHR_PIPELINE_EXECUTABLE_PROPERTIES_EXTENSION_NAME);
  if (has_executable_properties) { *tail = &fpe; tail = &fpe.pNext; }
  vkGetPhysicalDeviceFeatures2(pd, &feats);
  c.storage_16bit = f11.storageBuffer16BitAccess;
  c.storage_8bit = f12.storageBuffer8BitAccess;
  c.float16_arithmetic = f12.shaderFloat16;
  c.int8_arithmetic = f12.shaderInt8;
  c.subgroup_size_control = has_sgctl && fsg.subgroupSizeControl && fsg.computeFullSubgroups;
  c.float32_atomic_add = has_atomic_float && fat.shaderBufferFloat32AtomicAdd;
  c.vulkan_memory_model = f12.vulkanMemoryModel;
  c.pipeline_executable_info = has_executable_properties && fpe.pipelineExecutableInfo;
  c.cooperative_matrix2 = c.has_extension(VK_NV_COOPERATIVE_MATRIX_2_EXTENSION_NAME);
  c.cooperative_matrix2_facts = query_cooperative_matrix2(instance, pd, c.cooperative_matrix2);
  if (has_coopmat && fcm.cooperativeMatrix && instance != VK_NULL_HANDLE) {
    auto get = reinterpret_cast<PFN_vkGetPhysicalDeviceCooperativeMatrixPropertiesKHR>(
        vkGetInstanceProcAddr(instance, "vkGetPhysicalDeviceCooperativeMatrixPropertiesKHR"));
    uint32_t n = 0;
    if (get && get(pd, &n, nullptr) == VK_SUCCESS && n > 0) {
      VkCooperativeMatrixPropertiesKHR blank{};
      blank.sType = VK_STRUCTURE_TYPE_COOPERATIVE_MATRIX_PROPERTIES_KHR;
      std::vector<VkCooperativeMatrixPropertiesKHR> props(n, blank);
      if (get(pd, &n, props.data()) == VK_SUCCESS) {
        props.resize(n);
        for (const auto& p : props)
          c.cooperative_matrix_shapes.push_back({p.MSize, p.NSize, p.KSize, p.AType, p.BType, p.CType, p.ResultType,
                                                 p.saturatingAccumulation != VK_FALSE, p.scope});
      }
    }
  }
  // Usable only with the shapes known and the memory model the coopmat shaders are compiled for.
  c.cooperative_matrix = !c.cooperative_matrix_shapes.empty() && c.vulkan_memory_model &&
                         c.api_version >= VK_API_VERSION_1_3;
  const auto& cm2 = c.cooperative_matrix2_facts;
  c.cooperative_matrix2_row_ops =
      c.cooperative_matrix && cm2 && cm2->reductions && cm2->conversions && cm2->per_element_operations;
  // The coopmat2 kernels use fp16 arithmetic and buffers (Float16, StorageBuffer16BitAccess) as well.
  c.cooperative_matrix2_gemm = c.cooperative_matrix && c.storage_16bit && c.float16_arithmetic && cm2 &&
                               cm2->workgroup_scope && cm2->flexible_dimensions && cm2->tensor_addressing &&
                               cm2->per_element_operations;
  c.push_descriptor = c.has_extension("VK_KHR_push_descriptor");

  VkPhysicalDeviceMemoryProperties mem{};
  vkGetPhysicalDeviceMemoryProperties(pd, &mem);
  c.heaps.resize(mem.memoryHeapCount);
  for (uint32_t h = 0; h < mem.memoryHeapCount; ++h) {
    c.heaps[h].size = mem.memoryHeaps[h].size;
    c.heaps[h].device_local = mem.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT;
  }
  for (uint32_t t = 0; t < mem.memoryTypeCount; ++t)
    if (mem.memoryTypes[t].propertyFlags & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT)
      c.heaps[mem.memoryTypes[t].heapIndex].host_visible = true;
  c.memory_budget_ext = c.has_extension(VK_EXT_MEMORY_BUDGET_EXTENSION_NAME);
  c.memory_budget = query_memory_budget(pd, c.type, c.memory_budget_ext);
  apply_limit_overrides(c, limit_overrides_from_env());  // after the budget: memory= lowers it
  return c;
}

static std::string lower(std::string s) {
  for (char& ch : s) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  return s;
}

uint32_t select_device(const std::vector<DeviceCaps>& devices, const std::string& spec_in) {
  if (devices.empty())
    throw Error("No Vulkan device found. Install a Vulkan driver (for a CPU-only machine: apt-get install "
                "mesa-vulkan-drivers, which provides lavapipe).");
  std::string spec = spec_in;
  if (spec.empty())
    if (const char* env = std::getenv("DVS_DEVICE")) spec = env;
  if (spec.empty()) {
    for (VkPhysicalDeviceType want : {VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU, VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU,
                                      VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU})
      for (auto& d : devices)
        if (d.type == want) return d.index;
    return devices.front().index;
  }
  bool numeric = std::all_of(spec.begin(), spec.end(), [](char ch) { return std::isdigit(static_cast<unsigned char>(ch)); });
  if (numeric) {
    unsigned long idx = std::stoul(spec);
    for (auto& d : devices)
      if (d.index == idx) return d.index;
  } else {
    for (auto& d : devices)
      if (lower(d.name).find(lower(spec)) != std::string::npos) return d.index;
  }
  std::string list;
  for (auto& d : devices) list += "\n  " + std::to_string(d.index) + ": " + d.name + " (" + device_type_name(d.type) + ")";
  throw Error("No Vulkan device matches '" + spec + "' (from --device or DVS_DEVICE). Available devices:" + list +
              "\nGive an index or part of a name.");
}

int pick_compute_queue_family(const std::vector<VkQueueFamilyProperties>& families) {
  int first = -1;
  for (size_t i = 0; i < families.size(); ++i) {
    const VkQueueFlags f = families[i].queueFlags;
    if (!(f & VK_QUEUE_COMPUTE_BIT) || families[i].queueCount == 0) continue;
    if (!(f & VK_QUEUE_GRAPHICS_BIT)) return int(i);
    if (first < 0) first = int(i);
  }
  return first;
}

int pick_transfer_queue_family(const std::vector<VkQueueFamilyProperties>& families) {
  for (size_t i = 0; i < families.size(); ++i) {
    const VkQueueFlags f = families[i].queueFlags;
    if ((f & VK_QUEUE_TRANSFER_BIT) && !(f & (VK_QUEUE_GRAPHICS_BIT | VK_QUEUE_COMPUTE_BIT)) && families[i].queueCount > 0)
      return int(i);
  }
  return -1;
}

std::string describe_device(const DeviceCaps& c) {
  std::ostringstream o;
  auto forced = [](bool is, const std::string& device_value) { return is ? " * [" + device_value + "]" : std::string(); };
  auto yes = [](bool b) { return b ? "yes" : "no"; };
  o << "Device " << c.index << ": " << c.name << "\n"
    << "  type:                 " << device_type_name(c.type) << "\n"
    << "  driver:               " << c.driver_name << " " << c.driver_info << "\n"
    << "  Vulkan:               " << version_string(c.api_version) << "\n"
    << "  subgroup size:        " << c.subgroup_size;
  if (c.min_subgroup_size) o << " (size control " << c.min_subgroup_size << ".." << c.max_subgroup_size << ")";
  o << "\n"
    << "  16-bit storage:       " << yes(c.storage_16bit) << "\n"
    << "  8-bit storage:        " << yes(c.storage_8bit) << "\n"
    << "  fp16 arithmetic:      " << yes(c.float16_arithmetic) << "\n"
    << "  int8 arithmetic:      " << yes(c.int8_arithmetic) << "\n"
    << "  float32 atomic add:   " << yes(c.float32_atomic_add) << "\n"
    << "  cooperative matrix:   " << yes(c.cooperative_matrix)
    << (c.has_extension(VK_KHR_COOPERATIVE_MATRIX_EXTENSION_NAME) ? " (VK_KHR_cooperative_matrix)" : "")
    << (c.cooperative_matrix2 ? ", VK_NV_cooperative_matrix2" : "") << "\n";
  for (const CooperativeMatrixShape& s : c.cooperative_matrix_shapes)
    o << "    " << s.m << "x" << s.n << "x" << s.k << " " << cooperative_matrix_types_text(s.a, s.b, s.c, s.result) << " "
      << scope_name(s.scope) << (s.saturating ? " saturating" : "") << "\n";
  if (c.cooperative_matrix2_facts) print_cooperative_matrix2(o, *c.cooperative_matrix2_facts);
  o << "  pipeline statistics:  " << yes(c.pipeline_executable_info)
    << (c.pipeline_executable_info ? " (VK_KHR_pipeline_executable_properties: dvs-bench --filter gpu prints each kernel's)"
                                   : "") << "\n";
  o
    << "  subgroup arithmetic:  " << yes(c.subgroup_arithmetic) << "\n"
    << "  timestamps:           " << yes(c.timestamps) << " (" << c.timestamp_period_ns << " ns/tick)\n"
    << "  compute queue:        "
    << (!c.has_compute_queue ? std::string("none")
                             : "family " + std::to_string(c.queue_family) +
                                   (c.queue_compute_only ? " (compute-only)" : " (graphics + compute; no compute-only family)"))
    << "\n"
    << "  transfer queue:       "
    << (c.transfer_queue_family >= 0 ? "family " + std::to_string(c.transfer_queue_family) +
                                           " (transfer-only: streamed weights upload beside the compute)"
                                     : std::string("none (streamed weights upload on the compute queue)"))
    << "\n"
    << "  limits in force" << (c.forced_limits.any() ? " (* lowered by DVS_LIMITS; the device's value in brackets)" : "")
    << ":\n"
    << "  maxStorageBufferRange:      " << format_bytes(c.max_storage_buffer_range)
    << forced(c.forced_limits.binding, format_bytes(c.device_limits.binding)) << "\n"
    << "  maxTexelBufferElements:     " << c.max_texel_buffer_elements
    << forced(c.forced_limits.texels, std::to_string(c.device_limits.texels)) << "\n"
    << "  maxMemoryAllocationSize:    " << format_bytes(c.max_memory_allocation_size)
    << forced(c.forced_limits.alloc, format_bytes(c.device_limits.alloc)) << "\n"
    << "  maxComputeWorkGroupCount:   " << c.max_workgroup_count[0] << " x " << c.max_workgroup_count[1] << " x "
    << c.max_workgroup_count[2]
    << forced(c.forced_limits.groups, std::to_string(c.device_limits.groups[0]) + " x " +
                                          std::to_string(c.device_limits.groups[1]) + " x " +
                                          std::to_string(c.device_limits.groups[2])) << "\n"
    << "  maxComputeSharedMemorySize: " << format_bytes(c.max_compute_shared_memory) << "\n"
    << "  maxComputeWorkGroupInvocations: " << c.max_workgroup_invocations << "\n"
    << "  maxPushConstantsSize:       " << c.max_push_constants << " B\n"
    << "  memory heaps:\n";
  for (size_t h = 0; h < c.heaps.size(); ++h)
    o << "    heap " << h << ": " << format_bytes(c.heaps[h].size) << (c.heaps[h].device_local ? ", device-local" : "")
      << (c.heaps[h].host_visible ? ", host-visible" : "") << "\n";
  o << "  device memory for dvs: " << c.memory_budget.describe()
    << (c.forced_limits.memory ? " * lowered by DVS_LIMITS memory= [" + format_bytes(c.device_limits.memory) + "]" : "")
    << "\n";
  return o.str();
}

}  // namespace dvs::vk
