// Compute pipelines built from embedded SPIR-V plus specialization constants, memoised per (shader,
// constants), and an on-disk VkPipelineCache. The cache file carries its own header (device identity,
// driver version, a hash of every embedded shader, a checksum of the data) and is ignored whenever any
// of that does not match, so a driver update, another GPU or a corrupt file can never reach the driver.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <tuple>
#include <vector>

#include "vk/spirv_reflect.hpp"

namespace dvs::vk {

class Context;

struct Pipeline {
  std::string name;  // shader name, used for profiling labels and errors
  std::vector<uint32_t> spec;  // the specialization constants it was created with (which variant ran: tests)
  VkPipeline pipeline = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
  ShaderInterface iface;
  bool statistics_captured = false;  // created with VK_PIPELINE_CREATE_CAPTURE_STATISTICS_BIT_KHR
};

enum class CacheLoad { disabled, absent, loaded, rejected };

class PipelineCache {
 public:
  // file: path of the cache file; "" = default_file in the cache folder cache_dir; "-" = no disk cache.
  PipelineCache(Context& ctx, const std::string& file, const std::filesystem::path& cache_dir = {});
  ~PipelineCache();

  // Specialization constant i (constant_id = i) takes spec[i] (floats passed bit-cast).
  // required_subgroup_size (0: any): the shader's subgroups must have exactly that many lanes (kernels laid
  // out for one subgroup size, such as the tensor-core ones); required through subgroup size control with
  // full subgroups, or accepted where the device's only size is that one; else a dvs::Error naming both.
  const Pipeline& get(const std::string& shader, std::span<const uint32_t> spec = {},
                      uint32_t required_subgroup_size = 0);

  void save();  // writes the file atomically (temp name + rename); a no-op without a file
  CacheLoad load_state() const { return load_state_; }
  const std::string& load_note() const { return load_note_; }  // why a file was rejected
  const std::string& file() const { return file_; }
  size_t pipelines_created() const { return created_; }
  // Pipelines created from now on keep their compiled code's statistics where the device can report them
  // (caps.pipeline_executable_info; vk/pipeline_statistics.hpp reads them). For measurements: dvs-bench.
  void set_capture_statistics(bool on) { capture_statistics_ = on; }
  // Every pipeline created so far, in key order.
  void for_each(const std::function<void(const Pipeline&)>& fn) const {
    for (const auto& [key, p] : pipelines_) fn(*p);
  }

  // pipelines-<vendor>-<device>.bin in the cache folder cache_dir (io/cache_root.hpp: empty = $DVS_CACHE_DIR, else
  // ~/.cache/dvs), the folder whose inversions/ holds the run caches.
  static std::string default_file(const Context& ctx, const std::filesystem::path& cache_dir = {});

 private:
  void load();
  Context& ctx_;
  std::string file_;
  VkPipelineCache cache_ = VK_NULL_HANDLE;
  std::map<std::tuple<std::string, std::vector<uint32_t>, uint32_t>, std::unique_ptr<Pipeline>> pipelines_;
  CacheLoad load_state_ = CacheLoad::disabled;
  std::string load_note_;
  size_t created_ = 0;
  bool capture_statistics_ = false;
};

}  // namespace dvs::vk
