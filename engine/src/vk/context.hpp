// The Vulkan context: instance (with validation layers on request), the chosen physical device, a logical
// device with one compute queue and every optional feature dvs can use enabled, and the per-device
// services built on it (memory, pipelines, profiling).
#pragma once
#include <vulkan/vulkan.h>

#include <algorithm>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "vk/device_info.hpp"
#include "vk/device_limits.hpp"

namespace dvs::vk {

class Allocator;
class PipelineCache;
class Profiler;
class Transfer;

struct ContextOptions {
  std::string device;              // index or name substring; empty: DVS_DEVICE, else the best GPU
  bool validation = false;         // also on when DVS_VALIDATION=1
  std::string pipeline_cache_file; // empty: $DVS_CACHE_DIR or $XDG_CACHE_HOME/dvs or ~/.cache/dvs; "-": none
};

// Lists every device the loader sees (creates and destroys a private instance).
std::vector<DeviceCaps> list_devices();

class Context {
 public:
  explicit Context(const ContextOptions& options = {});
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  VkInstance instance() const { return instance_; }
  VkPhysicalDevice physical_device() const { return physical_; }
  VkDevice device() const { return device_; }
  VkQueue queue() const { return queue_; }
  uint32_t queue_family() const { return queue_family_; }
  const DeviceCaps& caps() const { return caps_; }
  // Lowers the limits in force further than DVS_LIMITS does (min of both), or back to DVS_LIMITS alone with
  // {} (tests that force one op's split paths: tests/support/scoped_limits.hpp). The allocator's existing
  // blocks are kept; new ones follow the new alloc limit.
  void override_limits(const LimitOverrides& extra);
  bool validation_enabled() const { return validation_; }
  // The largest buffer range any dispatch has bound since the last reset (storage or texel binding; Recorder
  // notes every one): benchmarks print it next to maxStorageBufferRange.
  void note_binding(VkDeviceSize bytes) { largest_binding_ = std::max(largest_binding_, bytes); }
  VkDeviceSize largest_binding() const { return largest_binding_; }
  void reset_largest_binding() { largest_binding_ = 0; }

  Allocator& allocator() { return *allocator_; }
  PipelineCache& pipelines() { return *pipelines_; }
  Profiler& profiler() { return *profiler_; }
  Transfer& transfer() { return *transfer_; }

  // Validation-layer messages (warnings and errors) received since the last clear.
  std::vector<std::string> validation_messages() const;
  void clear_validation_messages();
  void add_validation_message(std::string msg);

  // Submits one command buffer and waits for it (used by Transfer and Recorder).
  void submit_and_wait(VkCommandBuffer cmd);
  VkCommandPool command_pool() const { return command_pool_; }
  VkCommandBuffer allocate_command_buffer();  // primary, from the context's pool

 private:
  void release();

  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  uint32_t queue_family_ = 0;
  VkCommandPool command_pool_ = VK_NULL_HANDLE;
  VkFence fence_ = VK_NULL_HANDLE;
  DeviceCaps caps_;
  bool validation_ = false;
  VkDeviceSize largest_binding_ = 0;

  mutable std::mutex messages_mutex_;
  std::vector<std::string> messages_;

  std::unique_ptr<Allocator> allocator_;
  std::unique_ptr<Transfer> transfer_;
  std::unique_ptr<PipelineCache> pipelines_;
  std::unique_ptr<Profiler> profiler_;
};

}  // namespace dvs::vk
