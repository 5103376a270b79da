// Memory the application owns, handed to dvs without a round trip through files: host memory (a pointer and a
// shape) and device memory (a VkBuffer of the application's device, see dvs/context.hpp). dvs never frees,
// keeps or reallocates what a view points at; a view must stay valid until the call that takes it returns (for a
// device view: until the timeline value that call returns is reached).
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <string>
#include <vector>

#include "dvs/api.hpp"

namespace dvs {

enum class ElementType { f32, u8 };

// Contiguous row-major host memory. `data` may be const for inputs (the view never writes through an input).
struct DVS_API HostView {
  void* data = nullptr;
  ElementType type = ElementType::f32;
  std::vector<int64_t> shape;

  int64_t elements() const;
  uint64_t bytes() const;
  std::string describe() const;  // "f32[3x480x720]"
};

// Contiguous row-major elements in an application VkBuffer, from `offset` (a multiple of 4). The buffer must
// have been created with TRANSFER_SRC (inputs) / TRANSFER_DST (outputs) usage on the device of the context
// it is given to; dvs copies into or out of it on its queue, ordered by the context's timeline semaphore.
struct DVS_API DeviceBufferView {
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceSize offset = 0;
  ElementType type = ElementType::f32;
  std::vector<int64_t> shape;

  int64_t elements() const;
  uint64_t bytes() const;
};

}  // namespace dvs
