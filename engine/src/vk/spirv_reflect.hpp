// Just enough SPIR-V reflection to build a pipeline layout without hand-written tables: which descriptor
// bindings (set 0) a compute shader uses, their kind, and whether the shader only reads them (so the
// recorder knows which dispatches depend on which).
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <span>
#include <vector>

namespace dvs::vk {

enum class BindingKind { storage_buffer, uniform_buffer, uniform_texel_buffer, storage_texel_buffer };

struct ShaderBinding {
  uint32_t binding = 0;
  BindingKind kind = BindingKind::storage_buffer;
  bool read_only = false;
};

struct ShaderInterface {
  std::vector<ShaderBinding> bindings;  // sorted by binding number, one per number (aliases merged)
  uint32_t push_constant_bytes = 0;     // 0 if none (upper bound is the layout's 128 bytes)
  uint32_t local_size[3] = {1, 1, 1};   // literal LocalSize, when not from specialization constants
  // The module declares a combined image-sampler type over a texel buffer (GLSL samplerBuffer): invalid from
  // SPIR-V 1.6 on, rejected by current driver stacks. dvs shaders use textureBuffer instead (checked by
  // tests/test_shader_portability.cpp and at build time by cmake/shaders.cmake).
  bool combined_texel_buffer_sampler = false;
};

ShaderInterface reflect_shader(std::span<const uint32_t> spirv);

VkDescriptorType descriptor_type(BindingKind kind);

}  // namespace dvs::vk
