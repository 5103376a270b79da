// VK_CHECK: turns a failed Vulkan call into a dvs::Error naming the call and the VkResult.
#pragma once
#include <vulkan/vulkan.h>

#include <string>

#include "dvs/error.hpp"

namespace dvs::vk {

const char* result_name(VkResult r);
[[noreturn]] void throw_vk_error(VkResult r, const char* call, const char* file, int line);

}  // namespace dvs::vk

#define VK_CHECK(call)                                                           \
  do {                                                                           \
    VkResult vk_check_result_ = (call);                                          \
    if (vk_check_result_ != VK_SUCCESS)                                          \
      ::dvs::vk::throw_vk_error(vk_check_result_, #call, __FILE__, __LINE__);    \
  } while (0)
