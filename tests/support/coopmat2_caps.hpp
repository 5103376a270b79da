// Device facts of a GPU with VK_NV_cooperative_matrix2's workgroup scope and tensor addressing, for tests of which
// calls the coopmat2 kernels take (tensor/coopmat_layout.hpp, tensor/ops_conv_coopmat2.hpp) on a machine without one.
#pragma once
#include "vk/device_info.hpp"

namespace dvs::test {

// VK_COMPONENT_TYPE_BFLOAT16_KHR (VK_KHR_shader_bfloat16), newer than Debian 12's Vulkan headers.
inline const auto kBf16 = static_cast<VkComponentTypeKHR>(1000141000);

// The H200's VK_NV_cooperative_matrix2 facts (bench/results/h200-2026-11-29-info.txt): workgroup scope up to 256
// invocations, dimensions up to 1024, fp16 x fp16 + fp32 shapes at 16x16x16 (32 and 64 invocations), 32x16x16 (128)
// and 32x32x16 (256), and a bf16 one.
inline vk::DeviceCaps h200_like() {
  vk::DeviceCaps caps;
  caps.name = "H200-like";
  caps.cooperative_matrix = true;
  caps.cooperative_matrix2 = true;
  caps.cooperative_matrix2_gemm = true;
  vk::CooperativeMatrix2Facts f;
  f.workgroup_scope = f.flexible_dimensions = f.tensor_addressing = f.per_element_operations = true;
  f.workgroup_scope_max_workgroup_size = 256;
  f.flexible_dimensions_max_dimension = 1024;
  auto shape = [](uint32_t m, uint32_t n, uint32_t invocations, VkComponentTypeKHR ab) {
    vk::CooperativeMatrixFlexibleShape s;
    s.m_granularity = m, s.n_granularity = n, s.k_granularity = 16;
    s.a = s.b = ab;
    s.scope = VK_SCOPE_WORKGROUP_KHR;
    s.workgroup_invocations = invocations;
    return s;
  };
  f.flexible_shapes = {shape(16, 16, 32, VK_COMPONENT_TYPE_FLOAT16_KHR), shape(16, 16, 64, VK_COMPONENT_TYPE_FLOAT16_KHR),
                       shape(32, 16, 128, VK_COMPONENT_TYPE_FLOAT16_KHR), shape(32, 32, 256, VK_COMPONENT_TYPE_FLOAT16_KHR),
                       shape(32, 32, 256, kBf16)};
  caps.cooperative_matrix2_facts = f;
  return caps;
}

}  // namespace dvs::test
