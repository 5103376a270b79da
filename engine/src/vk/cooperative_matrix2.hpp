// VK_NV_cooperative_matrix2's device facts (issue 35 C.1): which of its features a device has, its workgroup-scope
// limits and the flexible-dimension shapes it offers. Reported by `dvs info` so a device run records what a
// coopmat2 kernel could use; no kernel uses the extension yet. Debian 12's Vulkan headers (1.3.239) predate it:
// the structures below are the registry's (vk.xml), declared only where the headers lack them.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <optional>
#include <ostream>
#include <vector>

#include "vk/cooperative_matrix_khr.hpp"

#ifndef VK_NV_cooperative_matrix2
#define VK_NV_cooperative_matrix2 1
#define VK_NV_COOPERATIVE_MATRIX_2_EXTENSION_NAME "VK_NV_cooperative_matrix2"
#define VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_COOPERATIVE_MATRIX_2_FEATURES_NV static_cast<VkStructureType>(1000593000)
#define VK_STRUCTURE_TYPE_COOPERATIVE_MATRIX_FLEXIBLE_DIMENSIONS_PROPERTIES_NV static_cast<VkStructureType>(1000593001)
#define VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_COOPERATIVE_MATRIX_2_PROPERTIES_NV static_cast<VkStructureType>(1000593002)

typedef struct VkPhysicalDeviceCooperativeMatrix2FeaturesNV {
  VkStructureType sType;
  void* pNext;
  VkBool32 cooperativeMatrixWorkgroupScope;
  VkBool32 cooperativeMatrixFlexibleDimensions;
  VkBool32 cooperativeMatrixReductions;
  VkBool32 cooperativeMatrixConversions;
  VkBool32 cooperativeMatrixPerElementOperations;
  VkBool32 cooperativeMatrixTensorAddressing;
  VkBool32 cooperativeMatrixBlockLoads;
} VkPhysicalDeviceCooperativeMatrix2FeaturesNV;

typedef struct VkPhysicalDeviceCooperativeMatrix2PropertiesNV {
  VkStructureType sType;
  void* pNext;
  uint32_t cooperativeMatrixWorkgroupScopeMaxWorkgroupSize;
  uint32_t cooperativeMatrixFlexibleDimensionsMaxDimension;
  uint32_t cooperativeMatrixWorkgroupScopeReservedSharedMemory;
} VkPhysicalDeviceCooperativeMatrix2PropertiesNV;

typedef struct VkCooperativeMatrixFlexibleDimensionsPropertiesNV {
  VkStructureType sType;
  void* pNext;
  uint32_t MGranularity;
  uint32_t NGranularity;
  uint32_t KGranularity;
  VkComponentTypeKHR AType;
  VkComponentTypeKHR BType;
  VkComponentTypeKHR CType;
  VkComponentTypeKHR ResultType;
  VkBool32 saturatingAccumulation;
  VkScopeKHR scope;
  uint32_t workgroupInvocations;
} VkCooperativeMatrixFlexibleDimensionsPropertiesNV;

typedef VkResult(VKAPI_PTR* PFN_vkGetPhysicalDeviceCooperativeMatrixFlexibleDimensionsPropertiesNV)(
    VkPhysicalDevice physicalDevice, uint32_t* pPropertyCount, VkCooperativeMatrixFlexibleDimensionsPropertiesNV* pProperties);
#endif

namespace dvs::vk {

// One flexible-dimension shape: M, N, K any multiples of the granularities, with these component types.
struct CooperativeMatrixFlexibleShape {
  uint32_t m_granularity = 0, n_granularity = 0, k_granularity = 0;
  VkComponentTypeKHR a = VK_COMPONENT_TYPE_FLOAT16_KHR, b = VK_COMPONENT_TYPE_FLOAT16_KHR,
                     c = VK_COMPONENT_TYPE_FLOAT32_KHR, result = VK_COMPONENT_TYPE_FLOAT32_KHR;
  bool saturating = false;
  VkScopeKHR scope = VK_SCOPE_SUBGROUP_KHR;
  uint32_t workgroup_invocations = 0;  // for workgroup scope: the workgroup size the shape needs
};

struct CooperativeMatrix2Facts {
  bool workgroup_scope = false, flexible_dimensions = false, reductions = false, conversions = false,
       per_element_operations = false, tensor_addressing = false, block_loads = false;
  uint32_t workgroup_scope_max_workgroup_size = 0, flexible_dimensions_max_dimension = 0,
           workgroup_scope_reserved_shared_memory = 0;
  std::vector<CooperativeMatrixFlexibleShape> flexible_shapes;
};

// The facts of a device that exposes VK_NV_cooperative_matrix2; nullopt for one that does not (`exposed` false).
// `instance` resolves the flexible-dimensions query (VK_NULL_HANDLE: the shapes stay empty).
std::optional<CooperativeMatrix2Facts> query_cooperative_matrix2(VkInstance instance, VkPhysicalDevice pd, bool exposed);

// `dvs info`'s lines for them (indented under "cooperative matrix").
void print_cooperative_matrix2(std::ostream& o, const CooperativeMatrix2Facts& f);

}  // namespace dvs::vk
