// dvs/views.hpp: sizes and descriptions of the application's memory views.
#include "dvs/views.hpp"

namespace dvs {
namespace {

int64_t product(const std::vector<int64_t>& shape) {
  int64_t n = 1;
  for (int64_t d : shape) n *= d;
  return shape.empty() ? 0 : n;
}

uint64_t element_bytes(ElementType t) { return t == ElementType::f32 ? 4 : 1; }

}  // namespace

int64_t HostView::elements() const { return product(shape); }
uint64_t HostView::bytes() const { return uint64_t(elements()) * element_bytes(type); }
std::string HostView::describe() const {
  std::string s = type == ElementType::f32 ? "f32[" : "u8[";
  for (size_t i = 0; i < shape.size(); ++i) s += (i ? "x" : "") + std::to_string(shape[i]);
  return s + "]";
}

int64_t DeviceBufferView::elements() const { return product(shape); }
uint64_t DeviceBufferView::bytes() const { return uint64_t(elements()) * element_bytes(type); }

std::string DeviceImageView::describe() const {
  std::string f;
  switch (format) {
    case VK_FORMAT_R8G8B8A8_UNORM: f = "VK_FORMAT_R8G8B8A8_UNORM"; break;
    case VK_FORMAT_R8G8B8A8_SRGB: f = "VK_FORMAT_R8G8B8A8_SRGB"; break;
    case VK_FORMAT_R32_SFLOAT: f = "VK_FORMAT_R32_SFLOAT"; break;
    case VK_FORMAT_UNDEFINED: f = "VK_FORMAT_UNDEFINED"; break;
    default: f = "VkFormat " + std::to_string(int(format));
  }
  return f + " " + std::to_string(width) + "x" + std::to_string(height);
}

}  // namespace dvs
