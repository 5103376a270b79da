// Every embedded shader is valid SPIR-V for current driver stacks: no combined image-sampler over a texel
// buffer (GLSL samplerBuffer/usamplerBuffer/isamplerBuffer), which SPIR-V 1.6 forbids ("Image Type operand of
// OpTypeSampledImage should not have a Dim of Buffer"). Texel-buffer inputs are textureBuffer, still bound as
// VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER. cmake/shaders.cmake checks the sources at build time; this checks
// what was actually embedded, and that reflection keeps deriving the uniform-texel-buffer descriptor.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "vk/shader_registry.hpp"
#include "vk/spirv_reflect.hpp"

namespace dvs {
namespace {

// A hand-assembled module: %img = OpTypeImage %float Buffer ... Sampled=1, then optionally
// %si = OpTypeSampledImage %img, and a UniformConstant variable of the image (or sampled image) at binding 3.
std::vector<uint32_t> texel_buffer_module(bool combined) {
  auto op = [](uint32_t code, uint32_t words) { return (words << 16) | code; };
  std::vector<uint32_t> w = {0x07230203u, 0x00010500u, 0, 20, 0};
  w.insert(w.end(), {op(71, 4), 10, 33, 3});                     // OpDecorate %10 Binding 3
  w.insert(w.end(), {op(22, 3), 1, 32});                         // %1 = OpTypeFloat 32
  w.insert(w.end(), {op(25, 9), 2, 1, 5, 0, 0, 0, 1, 0});        // %2 = OpTypeImage %1 Buffer 0 0 0 1 Unknown
  uint32_t var_type = 2;
  if (combined) {
    w.insert(w.end(), {op(27, 3), 3, 2});                        // %3 = OpTypeSampledImage %2
    var_type = 3;
  }
  w.insert(w.end(), {op(32, 4), 4, 0, var_type});                // %4 = OpTypePointer UniformConstant
  w.insert(w.end(), {op(59, 4), 4, 10, 0});                      // %10 = OpVariable %4 UniformConstant
  return w;
}

TEST(ShaderPortability, ReflectionSeesCombinedTexelBufferSamplers) {
  for (bool combined : {false, true}) {
    auto words = texel_buffer_module(combined);
    vk::ShaderInterface iface = vk::reflect_shader(words);
    EXPECT_EQ(iface.combined_texel_buffer_sampler, combined);
    ASSERT_EQ(iface.bindings.size(), 1u);
    EXPECT_EQ(iface.bindings[0].binding, 3u);
    // textureBuffer and samplerBuffer are the same descriptor: a uniform texel buffer, read-only.
    EXPECT_EQ(vk::descriptor_type(iface.bindings[0].kind), VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER);
    EXPECT_TRUE(iface.bindings[0].read_only);
  }
}

TEST(ShaderPortability, NoEmbeddedShaderUsesCombinedTexelBufferSamplers) {
  std::vector<std::string> offenders;
  size_t texel_inputs = 0;
  for (const std::string& name : vk::shader_names()) {
    vk::ShaderInterface iface = vk::reflect_shader(vk::find_shader(name));
    if (iface.combined_texel_buffer_sampler)
      offenders.push_back(name);
    for (const vk::ShaderBinding& b : iface.bindings)
      texel_inputs += b.kind == vk::BindingKind::uniform_texel_buffer;
  }
  EXPECT_TRUE(offenders.empty()) << "combined samplerBuffer in: " << ::testing::PrintToString(offenders)
                                 << " (declare textureBuffer + GL_EXT_samplerless_texture_functions instead)";
  EXPECT_GT(texel_inputs, 0u) << "no shader reads a uniform texel buffer: the scan would prove nothing";
}

// The converted shaders still reflect to uniform texel buffers at the bindings the ops bind them to.
TEST(ShaderPortability, ConvertedShadersKeepUniformTexelBufferBindings) {
  struct Expect { const char* shader; std::vector<uint32_t> texel_bindings; };
  const Expect expects[] = {
      {"nn/attention", {0, 1, 2, 4, 5}}, {"nn/attention_pack", {0, 1}}, {"nn/attention_pad", {0}}, {"linalg/linear", {0, 1}},
      {"linalg/linear_nosubgroup", {0, 1}}, {"nn/eltwise_binary_tex4", {0, 1}}, {"nn/eltwise_affine_tex4", {0, 1, 2}},
      {"nn/eltwise_unary_tex4", {0}}, {"nn/permute_tex4", {0}}, {"nn/concat_copy_tex4", {0}},
  };
  for (const Expect& e : expects) {
    vk::ShaderInterface iface = vk::reflect_shader(vk::find_shader(e.shader));
    EXPECT_FALSE(iface.combined_texel_buffer_sampler) << e.shader;
    std::vector<uint32_t> got;
    for (const vk::ShaderBinding& b : iface.bindings)
      if (b.kind == vk::BindingKind::uniform_texel_buffer) {
        got.push_back(b.binding);
        EXPECT_TRUE(b.read_only) << e.shader << " binding " << b.binding;
      }
    EXPECT_EQ(got, e.texel_bindings) << e.shader;
  }
}

// A binding that two variables alias (linear_coopmat reads X and W as elements and as 16-byte vectors) is one
// descriptor: the layout must not list it twice (vkCreateDescriptorSetLayout rejects duplicates), and it stays
// read-only only when every alias is; written aliases make it writable.
TEST(ShaderPortability, AliasedBindingsAreOneDescriptor) {
  vk::ShaderInterface iface = vk::reflect_shader(vk::find_shader("linalg/linear_coopmat"));
  ASSERT_EQ(iface.bindings.size(), 8u);
  for (uint32_t i = 0; i < 8; ++i) {
    EXPECT_EQ(iface.bindings[i].binding, i);
    EXPECT_EQ(iface.bindings[i].kind, vk::BindingKind::storage_buffer);
    EXPECT_EQ(iface.bindings[i].read_only, i != 2) << "binding " << i;  // 2 is Y
  }
}

}  // namespace
}  // namespace dvs
