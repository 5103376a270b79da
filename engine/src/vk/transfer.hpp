// Host <-> device copies. Mapped (unified) memory is a memcpy; otherwise data goes through a host-visible
// staging buffer in chunks with vkCmdCopyBuffer, so any size moves with a fixed staging footprint.
#pragma once
#include <vulkan/vulkan.h>

#include <cstddef>

#include "vk/memory.hpp"

namespace dvs::vk {

class Context;

class Transfer {
 public:
  explicit Transfer(Context& ctx);
  ~Transfer();
  void upload(const BufferView& dst, const void* src, size_t bytes);
  void download(const BufferView& src, void* dst, size_t bytes);
  void copy(const BufferView& src, const BufferView& dst, size_t bytes);  // device to device
  void fill_zero(const BufferView& dst);

  static constexpr size_t kStagingBytes = 32u << 20;
  // The staging buffers' size: kStagingBytes, or a quarter of one allocation where the limit in force is
  // lower (a copy then goes in more pieces).
  size_t staging_bytes() const;
  // Tests: route even mapped memory through the staging path that discrete GPUs use.
  void set_force_staging(bool on) { force_staging_ = on; }

 private:
  void run(void (*record)(VkCommandBuffer, void*), void* user);
  Context& ctx_;
  Buffer upload_staging_, readback_staging_;
  VkCommandBuffer cmd_ = VK_NULL_HANDLE;
  bool force_staging_ = false;
};

}  // namespace dvs::vk
