#include "vk/spirv_reflect.hpp"

#include <algorithm>
#include <map>
#include <set>

#include "dvs/error.hpp"

namespace dvs::vk {
namespace {
// Opcodes and enums from the SPIR-V specification (unified1).
enum : uint32_t {
  OpExecutionMode = 16, OpTypeImage = 25, OpTypeSampledImage = 27, OpTypeStruct = 30, OpTypePointer = 32,
  OpVariable = 59, OpDecorate = 71, OpMemberDecorate = 72,
  DecorationBlock = 2, DecorationBufferBlock = 3, DecorationNonWritable = 24, DecorationBinding = 33,
  DecorationDescriptorSet = 34,
  StorageUniform = 2, StoragePushConstant = 9, StorageStorageBuffer = 12, StorageUniformConstant = 0,
  DimBuffer = 5, ExecutionModeLocalSize = 17,
};
}  // namespace

ShaderInterface reflect_shader(std::span<const uint32_t> w) {
  if (w.size() < 5 || w[0] != 0x07230203u) throw Error("internal: not a SPIR-V module");
  std::map<uint32_t, uint32_t> binding_of, set_of;
  std::set<uint32_t> nonwritable_var, block_struct, buffer_block_struct;
  std::map<uint32_t, std::pair<uint32_t, uint32_t>> member_count_nonwritable;  // struct -> (members NW)
  std::map<uint32_t, uint32_t> struct_members;
  std::map<uint32_t, uint32_t> pointee;           // pointer type -> pointee type
  std::map<uint32_t, std::pair<uint32_t, uint32_t>> image_info;  // image type -> (dim, sampled)
  std::map<uint32_t, uint32_t> sampled_image_of;   // sampled image type -> image type
  struct Var { uint32_t id, type, storage; };
  std::vector<Var> vars;
  ShaderInterface out;

  for (size_t i = 5; i < w.size();) {
    uint32_t op = w[i] & 0xffff, n = w[i] >> 16;
    if (n == 0 || i + n > w.size()) throw Error("internal: malformed SPIR-V");
    const uint32_t* a = &w[i + 1];
    switch (op) {
      case OpDecorate:
        if (a[1] == DecorationBinding) binding_of[a[0]] = a[2];
        else if (a[1] == DecorationDescriptorSet) set_of[a[0]] = a[2];
        else if (a[1] == DecorationNonWritable) nonwritable_var.insert(a[0]);
        else if (a[1] == DecorationBlock) block_struct.insert(a[0]);
        else if (a[1] == DecorationBufferBlock) buffer_block_struct.insert(a[0]);
        break;
      case OpMemberDecorate:
        if (a[2] == DecorationNonWritable) member_count_nonwritable[a[0]].second++;
        break;
      case OpTypeStruct: struct_members[a[0]] = n - 2; break;
      case OpTypePointer: pointee[a[0]] = a[2]; break;
      case OpTypeImage: image_info[a[0]] = {a[2], a[6]}; break;
      case OpTypeSampledImage: sampled_image_of[a[0]] = a[1]; break;
      case OpVariable: vars.push_back({a[1], a[0], a[2]}); break;
      case OpExecutionMode:
        if (a[1] == ExecutionModeLocalSize && n >= 6) {
          out.local_size[0] = a[2];
          out.local_size[1] = a[3];
          out.local_size[2] = a[4];
        }
        break;
      default: break;
    }
    i += n;
  }

  for (const Var& v : vars) {
    uint32_t type = pointee.count(v.type) ? pointee[v.type] : 0;
    if (v.storage == StoragePushConstant) {
      out.push_constant_bytes = 128;  // layouts always declare the full guaranteed range
      continue;
    }
    if (!binding_of.count(v.id)) continue;
    if (set_of.count(v.id) && set_of[v.id] != 0) throw Error("internal: dvs shaders use descriptor set 0 only");
    ShaderBinding b;
    b.binding = binding_of[v.id];
    bool struct_ro = member_count_nonwritable.count(type) && struct_members.count(type) &&
                     member_count_nonwritable[type].second >= struct_members[type];
    if (v.storage == StorageStorageBuffer || (v.storage == StorageUniform && buffer_block_struct.count(type))) {
      b.kind = BindingKind::storage_buffer;
      b.read_only = nonwritable_var.count(v.id) || struct_ro;
    } else if (v.storage == StorageUniform) {
      b.kind = BindingKind::uniform_buffer;
      b.read_only = true;
    } else if (v.storage == StorageUniformConstant) {
      uint32_t img = sampled_image_of.count(type) ? sampled_image_of[type] : type;
      if (!image_info.count(img) || image_info[img].first != DimBuffer)
        throw Error("internal: only buffers and texel buffers are supported as shader resources");
      b.kind = image_info[img].second == 2 ? BindingKind::storage_texel_buffer : BindingKind::uniform_texel_buffer;
      b.read_only = b.kind == BindingKind::uniform_texel_buffer || nonwritable_var.count(v.id);
    } else {
      continue;
    }
    out.bindings.push_back(b);
  }
  for (const auto& [sampled, img] : sampled_image_of)
    if (image_info.count(img) && image_info[img].first == DimBuffer) out.combined_texel_buffer_sampler = true;
  std::sort(out.bindings.begin(), out.bindings.end(),
            [](const ShaderBinding& x, const ShaderBinding& y) { return x.binding < y.binding; });
  // Variables aliasing one binding (e.g. a buffer read as floats and as vec4): one descriptor, written when
  // any alias writes it.
  std::vector<ShaderBinding> merged;
  for (const ShaderBinding& b : out.bindings) {
    if (merged.empty() || merged.back().binding != b.binding) {
      merged.push_back(b);
      continue;
    }
    if (merged.back().kind != b.kind)
      throw Error("internal: binding " + std::to_string(b.binding) + " is declared as two kinds of descriptor");
    merged.back().read_only = merged.back().read_only && b.read_only;
  }
  out.bindings = std::move(merged);
  return out;
}

VkDescriptorType descriptor_type(BindingKind k) {
  switch (k) {
    case BindingKind::storage_buffer: return VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
    case BindingKind::uniform_buffer: return VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
    case BindingKind::uniform_texel_buffer: return VK_DESCRIPTOR_TYPE_UNIFORM_TEXEL_BUFFER;
    case BindingKind::storage_texel_buffer: return VK_DESCRIPTOR_TYPE_STORAGE_TEXEL_BUFFER;
  }
  return VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
}

}  // namespace dvs::vk
