// Uploads that run beside the compute: copies from host memory the device reads directly (MemoryUse::pinned)
// into device buffers (MemoryUse::device_shared), submitted to the context's transfer queue (a copy engine where
// the device has one, else the compute queue itself) and ordered with the compute by timeline semaphores only:
// each upload waits on the GPU until the context's timeline reaches a given value (the compute that last read
// its destination), and signals this queue's own timeline, on which the compute that reads it waits
// (Context::wait_before_next). The host never waits in between. models/block_stream.hpp schedules it.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <vector>

#include "vk/memory.hpp"

namespace dvs::vk {

class Context;
class TimestampQueries;

class UploadQueue {
 public:
  explicit UploadQueue(Context& ctx);
  ~UploadQueue();  // waits for every upload still running
  UploadQueue(const UploadQueue&) = delete;
  UploadQueue& operator=(const UploadQueue&) = delete;

  // One copy of an upload: `bytes` from `src` to `dst`.
  struct Copy {
    BufferView src, dst;
    VkDeviceSize bytes = 0;
  };
  // Makes `copies` (one submission) once the context's timeline has reached `after`; returns the value this
  // upload signals on timeline() (1, 2, 3, ... in submission order). With `stamps`, the device's clock when the
  // upload starts and when its copies are done go to queries `first_query` and `first_query` + 1.
  uint64_t upload(const std::vector<Copy>& copies, uint64_t after, const TimestampQueries* stamps = nullptr,
                  uint32_t first_query = 0);
  uint64_t upload(const BufferView& src, const BufferView& dst, VkDeviceSize bytes, uint64_t after) {
    return upload({Copy{src, dst, bytes}}, after);
  }
  VkSemaphore timeline() const { return timeline_; }
  uint64_t submitted() const { return submitted_; }  // the last value upload() returned
  uint64_t completed() const;                          // the timeline's value now
  void wait(uint64_t value);                           // host wait (never for an upload not submitted yet)
  void wait_all() { wait(submitted_); }
  bool on_compute_queue() const;  // the device has no transfer-only family

 private:
  void recycle();  // frees the command buffers of finished uploads

  Context& ctx_;
  VkCommandPool pool_ = VK_NULL_HANDLE;
  VkSemaphore timeline_ = VK_NULL_HANDLE;
  uint64_t submitted_ = 0;
  std::vector<std::pair<uint64_t, VkCommandBuffer>> in_flight_;  // signal value, its command buffer
};

}  // namespace dvs::vk
