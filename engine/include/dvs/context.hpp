// A dvs context: the Vulkan device dvs works on, either its own (created and destroyed by dvs) or the
// application's (HostDevice: dvs checks what it needs, creates only its own pools, buffers and pipelines on it, and
// never destroys the instance, device or queue).
//
// Ordering with the application: every submission dvs makes signals the context's timeline semaphore with the
// next value; calls that return a `uint64_t` ticket return that value, so the application can wait for it on the
// host (Context::wait) or on its own queue (a VkTimelineSemaphoreSubmitInfo wait on timeline()). The other way,
// wait_before_next() makes dvs's next submission wait for a semaphore value the application signals.
//
// Threads: calls on one context from several threads are serialised (each waits for the one running); while a job
// runs on the context (dvs::start_pipeline on a clip) a call from another thread is refused with a dvs::Error
// (ErrorKind::invalid_argument) naming the job: for work beside a job (a preview render loop), make a second
// Context on the same device (docs/embedding.md, "A preview beside a job"). Distinct contexts are independent,
// also on one HostDevice (dvs serialises its own submissions to a shared VkQueue).
//
// Lifetime: what is made on a context (a PointCloudScene, a DepthEstimator) keeps its device objects alive, so the
// Context may be destroyed first; the device objects go with the last of them (on a HostDevice, destroy them all
// before the application's VkDevice). Destroying a Context cancels a job running on it and waits for its end.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "dvs/api.hpp"
#include "dvs/devices.hpp"

namespace dvs {

namespace vk {
class Context;
}
namespace embed {
struct ContextCore;
}

// The application's Vulkan objects. The device must have been created with the features and extensions
// Context::required_features() lists (Vulkan 1.2 with timelineSemaphore; the optional ones dvs uses when enabled),
// and `queue` must come from `queue_family`, which must support compute and transfer.
struct HostDevice {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical_device = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  uint32_t queue_family = 0;
  VkQueue queue = VK_NULL_HANDLE;
  // The Vulkan version the application created its instance with (VkApplicationInfo::apiVersion); ≥ 1.2.
  uint32_t instance_api_version = VK_API_VERSION_1_2;
  // What the application enabled when it created the device (dvs cannot read it back from `device`): the
  // VkDeviceCreateInfo::pNext feature chain (VkPhysicalDeviceFeatures2 and/or VkPhysicalDeviceVulkan11/12/13Features
  // or the individual feature structures; read only while the Context is constructed) and the
  // ppEnabledExtensionNames. dvs uses an optional feature only where both say it is on.
  const void* enabled_features = nullptr;
  std::vector<std::string> enabled_extensions;
  // Optional external lock: called around every vkQueueSubmit / vkQueueWaitIdle dvs makes on `queue`, for a
  // queue the application also submits to from other threads (Vulkan requires external synchronisation).
  std::function<void()> lock_queue, unlock_queue;
};

struct ContextOptions {
  std::string device;        // dvs's own device only: index or name substring; "" = DVS_DEVICE, else the best GPU
  bool validation = false;   // dvs's own device only: the Khronos validation layer (also DVS_VALIDATION=1)
  std::string pipeline_cache_file;  // "" = $DVS_CACHE_DIR or ~/.cache/dvs; "-" = none
};

class DVS_API Context {
 public:
  // dvs's own instance and device (what the dvs program uses).
  explicit Context(const ContextOptions& options = {});
  // The application's device. Throws dvs::Error naming every missing feature or extension.
  explicit Context(const HostDevice& host, const ContextOptions& options = {});
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  // What a HostDevice must offer: "Vulkan 1.2", "timelineSemaphore", ... (required), and what dvs enables when the
  // device was created with it (optional: 16-bit storage, float16, shader atomic float, ...).
  static std::vector<std::string> required_features();
  static std::vector<std::string> optional_features();

  std::string device_name() const;
  DeviceLimits limits() const;
  bool owns_device() const;  // false for a HostDevice

  // The timeline semaphore dvs signals after each submission, and the last value it has submitted.
  VkSemaphore timeline() const;
  uint64_t submitted_value() const;
  // Blocks until the timeline reaches `ticket` (at most timeout_ns; false when it timed out).
  bool wait(uint64_t ticket, uint64_t timeout_ns = UINT64_MAX) const;
  // dvs's next submission waits until `semaphore` (a timeline semaphore of the same device) reaches `value`.
  void wait_before_next(VkSemaphore semaphore, uint64_t value);

  // dvs's own code only (not part of the stable API): the device objects, and what the context shares with what is
  // made on it.
  vk::Context& internal();
  std::shared_ptr<embed::ContextCore> core() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dvs
