#include "vk/cooperative_matrix2.hpp"

#include "vk/device_info.hpp"

namespace dvs::vk {

std::optional<CooperativeMatrix2Facts> query_cooperative_matrix2(VkInstance instance, VkPhysicalDevice pd, bool exposed) {
  if (!exposed) return std::nullopt;
  CooperativeMatrix2Facts f;
  VkPhysicalDeviceCooperativeMatrix2FeaturesNV feats{};
  feats.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_COOPERATIVE_MATRIX_2_FEATURES_NV;
  VkPhysicalDeviceFeatures2 f2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2};
  f2.pNext = &feats;
  vkGetPhysicalDeviceFeatures2(pd, &f2);
  f.workgroup_scope = feats.cooperativeMatrixWorkgroupScope;
  f.flexible_dimensions = feats.cooperativeMatrixFlexibleDimensions;
  f.reductions = feats.cooperativeMatrixReductions;
  f.conversions = feats.cooperativeMatrixConversions;
  f.per_element_operations = feats.cooperativeMatrixPerElementOperations;
  f.tensor_addressing = feats.cooperativeMatrixTensorAddressing;
  f.block_loads = feats.cooperativeMatrixBlockLoads;

  VkPhysicalDeviceCooperativeMatrix2PropertiesNV props{};
  props.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_COOPERATIVE_MATRIX_2_PROPERTIES_NV;
  VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  p2.pNext = &props;
  vkGetPhysicalDeviceProperties2(pd, &p2);
  f.workgroup_scope_max_workgroup_size = props.cooperativeMatrixWorkgroupScopeMaxWorkgroupSize;
  f.flexible_dimensions_max_dimension = props.cooperativeMatrixFlexibleDimensionsMaxDimension;
  f.workgroup_scope_reserved_shared_memory = props.cooperativeMatrixWorkgroupScopeReservedSharedMemory;

  if (f.flexible_dimensions && instance != VK_NULL_HANDLE) {
    auto get = reinterpret_cast<PFN_vkGetPhysicalDeviceCooperativeMatrixFlexibleDimensionsPropertiesNV>(
        vkGetInstanceProcAddr(instance, "vkGetPhysicalDeviceCooperativeMatrixFlexibleDimensionsPropertiesNV"));
    uint32_t n = 0;
    if (get && get(pd, &n, nullptr) == VK_SUCCESS && n > 0) {
      VkCooperativeMatrixFlexibleDimensionsPropertiesNV blank{};
      blank.sType = VK_STRUCTURE_TYPE_COOPERATIVE_MATRIX_FLEXIBLE_DIMENSIONS_PROPERTIES_NV;
      std::vector<VkCooperativeMatrixFlexibleDimensionsPropertiesNV> shapes(n, blank);
      if (get(pd, &n, shapes.data()) == VK_SUCCESS) {
        shapes.resize(n);
        for (const auto& s : shapes)
          f.flexible_shapes.push_back({s.MGranularity, s.NGranularity, s.KGranularity, s.AType, s.BType, s.CType,
                                       s.ResultType, s.saturatingAccumulation != VK_FALSE, s.scope,
                                       s.workgroupInvocations});
      }
    }
  }
  return f;
}

void print_cooperative_matrix2(std::ostream& o, const CooperativeMatrix2Facts& f) {
  auto yes = [](bool b) { return b ? "yes" : "no"; };
  o << "    coopmat2 features:  workgroup scope " << yes(f.workgroup_scope) << ", flexible dimensions "
    << yes(f.flexible_dimensions) << ", reductions " << yes(f.reductions) << ", conversions " << yes(f.conversions)
    << ", per-element operations " << yes(f.per_element_operations) << ", tensor addressing "
    << yes(f.tensor_addressing) << ", block loads " << yes(f.block_loads) << "\n"
    << "    coopmat2 limits:    workgroup scope up to " << f.workgroup_scope_max_workgroup_size
    << " invocations (" << f.workgroup_scope_reserved_shared_memory << " B shared memory reserved), flexible dimensions up to "
    << f.flexible_dimensions_max_dimension << "\n";
  for (const CooperativeMatrixFlexibleShape& s : f.flexible_shapes) {
    o << "    coopmat2 flexible:  " << s.m_granularity << "x" << s.n_granularity << "x" << s.k_granularity
      << " granularity " << cooperative_matrix_types_text(s.a, s.b, s.c, s.result) << " " << scope_name(s.scope);
    if (s.scope == VK_SCOPE_WORKGROUP_KHR) o << " (" << s.workgroup_invocations << " invocations)";
    o << (s.saturating ? " saturating" : "") << "\n";
  }
}

}  // namespace dvs::vk
