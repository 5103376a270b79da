// GPU timestamps for tests and dvs-bench: when the device reached a point of its work on its own clock, not when
// the host submitted it (a wall-clock timing would measure the host). Streamed weights use them to show, on the
// device's timeline, where each upload ran against the compute (models/block_stream.hpp, record_timestamps).
// Timestamps are only comparable when written on one queue (Vulkan's rule): comparable() says whether the
// uploads' and the compute's are.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <vector>

namespace dvs::vk {

class Context;

class TimestampQueries {
 public:
  // A query pool of `count` timestamps. Throws dvs::Error when the device has no timestamps on its compute queue.
  TimestampQueries(Context& ctx, uint32_t count);
  ~TimestampQueries();
  TimestampQueries(const TimestampQueries&) = delete;
  TimestampQueries& operator=(const TimestampQueries&) = delete;

  uint32_t count() const { return count_; }
  // Records into `cmd` (any queue of the device whose family has timestamps): query `query` reset, then its
  // timestamp written once the commands before it reach `stage`.
  void record(VkCommandBuffer cmd, uint32_t query, VkPipelineStageFlagBits stage) const;
  // Submits to the compute queue a command buffer that only writes timestamp `query` (one submission of the
  // context's timeline, after what Context::wait_before_next asked).
  void mark(uint32_t query);
  // Timestamps first .. first + n - 1 in nanoseconds on the device's clock, once written (waits for them: each must
  // have been recorded and submitted).
  std::vector<double> read_ns(uint32_t first, uint32_t n) const;

 private:
  Context& ctx_;
  VkQueryPool pool_ = VK_NULL_HANDLE;
  uint32_t count_ = 0;
  uint64_t last_mark_ = 0;  // the ticket of the last mark(): the destructor waits for it
};

}  // namespace dvs::vk
