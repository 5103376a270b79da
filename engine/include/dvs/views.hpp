// Memory the application owns, handed to dvs without a round trip through files: host memory (a pointer and a
// shape) and device memory (a VkBuffer or a 2-D VkImage of the application's device, see dvs/context.hpp). dvs never frees,
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

// Contiguous row-major host memory dvs writes: a call's outputs.
struct DVS_API HostView {
  void* data = nullptr;
  ElementType type = ElementType::f32;
  std::vector<int64_t> shape;

  int64_t elements() const;
  uint64_t bytes() const;
  std::string describe() const;  // "f32[3x480x720]"
};

// The same, read only: a call's inputs, which take const memory (a const std::vector's data()); any HostView
// converts to one.
struct DVS_API ConstHostView {
  const void* data = nullptr;
  ElementType type = ElementType::f32;
  std::vector<int64_t> shape;

  ConstHostView() = default;
  ConstHostView(const void* data, ElementType type, std::vector<int64_t> shape);
  ConstHostView(const HostView& view);  // implicit: memory dvs may write, it may also read

  int64_t elements() const;
  uint64_t bytes() const;
  std::string describe() const;  // as HostView's
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
  std::string describe() const;  // "u8[9x480x720x3]", as HostView's
};

// A 2-D VkImage of the context's device: one mip level, one array layer, colour. Created with TRANSFER_DST usage
// (dvs writes it) or TRANSFER_SRC (dvs reads it), exclusive to the context's queue family or
// VK_SHARING_MODE_CONCURRENT. Formats: VK_FORMAT_R8G8B8A8_UNORM for images (not _SRGB: the bytes are the render's
// own levels, an sRGB view would convert them), VK_FORMAT_R32_SFLOAT for masks. dvs moves the image from `layout`
// (the layout it is in when dvs's work starts; UNDEFINED = its contents may be discarded) to the transfer layout and,
// in the same submission, to `final_layout` (e.g. SHADER_READ_ONLY_OPTIMAL or TRANSFER_SRC_OPTIMAL), where the
// application finds it once the returned ticket is reached. Vulkan cannot report an image's size, format or usage:
// dvs trusts width, height and format, and the validation layer catches an image that differs.
struct DVS_API DeviceImageView {
  VkImage image = VK_NULL_HANDLE;
  VkFormat format = VK_FORMAT_UNDEFINED;
  uint32_t width = 0, height = 0;
  VkImageLayout layout = VK_IMAGE_LAYOUT_UNDEFINED;
  VkImageLayout final_layout = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;

  std::string describe() const;  // "VK_FORMAT_R8G8B8A8_UNORM 720x480"
};

}  // namespace dvs
