// VK_CHECK: turns a failed Vulkan call into a dvs::Error naming the call and the VkResult. Running out of
// device memory and losing the device have types of their own: the stage that meets them adds what to do
// (StageTracker: the memory plan's figures for that stage, which options help).
#pragma once
#include <vulkan/vulkan.h>

#include <string>

#include "dvs/error.hpp"

namespace dvs::vk {

// The device could not give dvs the memory it asked for (the allocator's budget check or the driver).
// `hint` is the generic advice, replaced by the stage's own where the stage is known.
class DeviceOutOfMemory : public Error {
 public:
  DeviceOutOfMemory(const std::string& detail, const std::string& hint)
      : Error(detail + hint, ErrorKind::out_of_memory), detail_(detail) {}
  const std::string& detail() const { return detail_; }

 private:
  std::string detail_;
};

// VK_ERROR_DEVICE_LOST: the driver reset the device; nothing on it survives.
class DeviceLost : public Error {
 public:
  explicit DeviceLost(const std::string& what) : Error(what, ErrorKind::device_lost) {}
};

// The advice an out-of-memory error gives where no stage knows better.
extern const char* const kOutOfMemoryHint;

const char* result_name(VkResult r);
[[noreturn]] void throw_vk_error(VkResult r, const char* call, const char* file, int line);

}  // namespace dvs::vk

#define VK_CHECK(call)                                                           \
  do {                                                                           \
    VkResult vk_check_result_ = (call);                                          \
    if (vk_check_result_ != VK_SUCCESS)                                          \
      ::dvs::vk::throw_vk_error(vk_check_result_, #call, __FILE__, __LINE__);    \
  } while (0)
