#include "vk/pipeline.hpp"

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <unistd.h>

#include "io/cache_root.hpp"
#include "dvs/error.hpp"
#include "io/injected_faults.hpp"
#include "io/library_log.hpp"
#include "vk/check.hpp"
#include "vk/context.hpp"
#include "vk/shader_registry.hpp"

namespace dvs::vk {
namespace {

constexpr char kMagic[8] = {'D', 'V', 'S', 'P', 'C', 'v', '1', 0};

struct FileHeader {
  char magic[8];
  uint32_t vendor_id, device_id, driver_version, reserved;
  uint8_t uuid[VK_UUID_SIZE];
  uint64_t shaders_hash, data_size, data_hash;
};

uint64_t fnv1a(const uint8_t* p, size_t n) {
  uint64_t h = 1469598103934665603ull;
  for (size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}

FileHeader expected_header(const DeviceCaps& c) {
  FileHeader h{};
  std::memcpy(h.magic, kMagic, sizeof kMagic);
  h.vendor_id = c.vendor_id;
  h.device_id = c.device_id;
  h.driver_version = c.driver_version;
  std::memcpy(h.uuid, c.pipeline_cache_uuid, VK_UUID_SIZE);
  h.shaders_hash = shaders_hash();
  return h;
}


}  // namespace

std::string PipelineCache::default_file(const Context& ctx, const std::filesystem::path& cache_dir) {
  char name[64];
  std::snprintf(name, sizeof name, "pipelines-%04x-%04x.bin", ctx.caps().vendor_id, ctx.caps().device_id);
  return (cache_root(cache_dir) / name).string();
}

PipelineCache::PipelineCache(Context& ctx, const std::string& file, const std::filesystem::path& cache_dir) : ctx_(ctx) {
  file_ = file == "-" ? "" : (file.empty() ? default_file(ctx, cache_dir) : file);
  load();
}

void PipelineCache::load() {
  std::vector<uint8_t> data;
  if (file_.empty()) {
    load_state_ = CacheLoad::disabled;
  } else {
    std::ifstream in(file_, std::ios::binary);
    if (!in) {
      load_state_ = CacheLoad::absent;
    } else {
      std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
      FileHeader want = expected_header(ctx_.caps()), got{};
      if (bytes.size() < sizeof(FileHeader)) {
        load_note_ = "file shorter than its header";
      } else {
        std::memcpy(&got, bytes.data(), sizeof got);
        if (std::memcmp(got.magic, want.magic, 8) != 0) load_note_ = "not a dvs pipeline cache";
        else if (got.vendor_id != want.vendor_id || got.device_id != want.device_id ||
                 std::memcmp(got.uuid, want.uuid, VK_UUID_SIZE) != 0)
          load_note_ = "written for another device";
        else if (got.driver_version != want.driver_version) load_note_ = "written by another driver version";
        else if (got.shaders_hash != want.shaders_hash) load_note_ = "written for other shaders";
        else if (got.data_size != bytes.size() - sizeof(FileHeader)) load_note_ = "truncated or padded";
        else if (got.data_hash != fnv1a(bytes.data() + sizeof(FileHeader), got.data_size)) load_note_ = "checksum mismatch";
        else data.assign(bytes.begin() + sizeof(FileHeader), bytes.end());
      }
      load_state_ = load_note_.empty() ? CacheLoad::loaded : CacheLoad::rejected;
    }
  }
  VkPipelineCacheCreateInfo ci{VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO};
  ci.initialDataSize = data.size();
  ci.pInitialData = data.empty() ? nullptr : data.data();
  VkResult r = vkCreatePipelineCache(ctx_.device(), &ci, nullptr, &cache_);
  if (r != VK_SUCCESS && !data.empty()) {  // the driver refused it after all: start empty
    load_state_ = CacheLoad::rejected;
    load_note_ = "driver rejected the data";
    ci.initialDataSize = 0;
    ci.pInitialData = nullptr;
    r = vkCreatePipelineCache(ctx_.device(), &ci, nullptr, &cache_);
  }
  VK_CHECK(r);
}

PipelineCache::~PipelineCache() {
  try {
    if (created_) save();
  } catch (const std::exception& e) {
    log_warning(std::string("could not save the pipeline cache: ") + e.what());
  }
  VkDevice dev = ctx_.device();
  for (auto& [key, p] : pipelines_) {
    vkDestroyPipeline(dev, p->pipeline, nullptr);
    vkDestroyPipelineLayout(dev, p->layout, nullptr);
    vkDestroyDescriptorSetLayout(dev, p->set_layout, nullptr);
  }
  if (cache_) vkDestroyPipelineCache(dev, cache_, nullptr);
}

void PipelineCache::save() {
  if (file_.empty()) return;
  size_t size = 0;
  VK_CHECK(vkGetPipelineCacheData(ctx_.device(), cache_, &size, nullptr));
  std::vector<uint8_t> data(size);
  VK_CHECK(vkGetPipelineCacheData(ctx_.device(), cache_, &size, data.data()));
  data.resize(size);
  FileHeader h = expected_header(ctx_.caps());
  h.data_size = size;
  h.data_hash = fnv1a(data.data(), size);
  std::filesystem::path path(file_);
  std::error_code ec;
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path(), ec);
  // A name of this save's own: two contexts of one process (a preview beside a job) may save the same file at once.
  static std::atomic<uint64_t> saves{0};
  std::string tmp = file_ + ".tmp" + std::to_string(::getpid()) + "-" + std::to_string(++saves);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return;  // an unwritable cache directory only costs start-up time
    out.write(reinterpret_cast<const char*>(&h), sizeof h);
    out.write(reinterpret_cast<const char*>(data.data()), std::streamsize(size));
    out.close();
    if (!out || faults::write_error(path)) {
      std::filesystem::remove(tmp, ec);
      return;
    }
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) std::filesystem::remove(tmp, ec);
}

const Pipeline& PipelineCache::get(const std::string& shader, std::span<const uint32_t> spec,
                                   uint32_t required_subgroup_size) {
  auto key = std::make_tuple(shader, std::vector<uint32_t>(spec.begin(), spec.end()), required_subgroup_size);
  if (auto it = pipelines_.find(key); it != pipelines_.end()) return *it->second;
  // Through size control where the device offers it for compute (SPIR-V 1.6 shaders may otherwise see any
  // size it supports); a device without it runs compute at its one subgroup size.
  const DeviceCaps& caps = ctx_.caps();
  const uint32_t lanes = required_subgroup_size;
  const bool require = lanes && caps.subgroup_size_control && caps.compute_required_subgroup_size &&
                       lanes >= caps.min_subgroup_size && lanes <= caps.max_subgroup_size;
  if (lanes && !require && !(caps.subgroup_size == lanes && (!caps.subgroup_size_control ||
                                                             caps.min_subgroup_size == caps.max_subgroup_size)))
    throw Error("shader " + shader + " is laid out for subgroups of " + std::to_string(lanes) + " lanes; " +
                caps.name + " runs compute with subgroups of " +
                (caps.subgroup_size_control && caps.min_subgroup_size
                     ? std::to_string(caps.min_subgroup_size) + " to " + std::to_string(caps.max_subgroup_size) +
                           (caps.compute_required_subgroup_size ? "" : " (not selectable for compute)")
                     : std::to_string(caps.subgroup_size)) +
                " lanes (choose the layout for this device in DVS_TUNING: coopmat_lanes)");

  std::span<const uint32_t> code = find_shader(shader);
  auto p = std::make_unique<Pipeline>();
  p->name = shader;
  p->spec.assign(spec.begin(), spec.end());
  p->iface = reflect_shader(code);
  VkDevice dev = ctx_.device();

  std::vector<VkDescriptorSetLayoutBinding> lb;
  for (const ShaderBinding& b : p->iface.bindings)
    lb.push_back({b.binding, descriptor_type(b.kind), 1, VK_SHADER_STAGE_COMPUTE_BIT, nullptr});
  VkDescriptorSetLayoutCreateInfo dl{VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO};
  dl.bindingCount = uint32_t(lb.size());
  dl.pBindings = lb.data();
  VK_CHECK(vkCreateDescriptorSetLayout(dev, &dl, nullptr, &p->set_layout));

  VkPushConstantRange pcr{VK_SHADER_STAGE_COMPUTE_BIT, 0, 128};
  VkPipelineLayoutCreateInfo pl{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  pl.setLayoutCount = 1;
  pl.pSetLayouts = &p->set_layout;
  pl.pushConstantRangeCount = p->iface.push_constant_bytes ? 1 : 0;
  pl.pPushConstantRanges = &pcr;
  VK_CHECK(vkCreatePipelineLayout(dev, &pl, nullptr, &p->layout));

  VkShaderModuleCreateInfo smi{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
  smi.codeSize = code.size() * 4;
  smi.pCode = code.data();
  VkShaderModule module = VK_NULL_HANDLE;
  VK_CHECK(vkCreateShaderModule(dev, &smi, nullptr, &module));

  std::vector<VkSpecializationMapEntry> entries;
  for (uint32_t i = 0; i < spec.size(); ++i) entries.push_back({i, i * 4, 4});
  VkSpecializationInfo si{uint32_t(entries.size()), entries.data(), spec.size() * 4, spec.data()};
  VkComputePipelineCreateInfo ci{VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO};
  ci.stage = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  ci.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
  ci.stage.module = module;
  ci.stage.pName = "main";
  ci.stage.pSpecializationInfo = spec.empty() ? nullptr : &si;
  VkPipelineShaderStageRequiredSubgroupSizeCreateInfo sized{
      VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_REQUIRED_SUBGROUP_SIZE_CREATE_INFO};
  if (require) {
    sized.requiredSubgroupSize = lanes;
    ci.stage.pNext = &sized;
    ci.stage.flags = VK_PIPELINE_SHADER_STAGE_CREATE_REQUIRE_FULL_SUBGROUPS_BIT;
  }
  ci.layout = p->layout;
  if (capture_statistics_ && caps.pipeline_executable_info) {
    ci.flags |= VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR;
    p->statistics_captured = true;
  }
  VkResult r = vkCreateComputePipelines(dev, cache_, 1, &ci, nullptr, &p->pipeline);
  vkDestroyShaderModule(dev, module, nullptr);
  VK_CHECK(r);
  ctx_.name_object(VK_OBJECT_TYPE_PIPELINE, uint64_t(p->pipeline), p->name);
  created_++;
  const Pipeline& ref = *p;
  pipelines_.emplace(std::move(key), std::move(p));
  return ref;
}

}  // namespace dvs::vk
