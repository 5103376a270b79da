// dvs/views.hpp: sizes and descriptions of the application's memory views.
#include "dvs/views.hpp"

#include <utility>

namespace dvs {
namespace {

int64_t product(const std::vector<int64_t>& shape) {
  int64_t n = 1;
  for (int64_t d : shape) n *= d;
  return shape.empty() ? 0 : n;
}

uint64_t element_bytes(ElementType t) { return t == ElementType::f32 ? 4 : 1; }

std::string describe(ElementType type, const std::vector<int64_t>& shape) {
  std::string s = type == ElementType::f32 ? "f32[" : "u8[";
  for (size_t i = 0; i < shape.size(); ++i) {
    if (i) s += 'x';
    s += std::to_string(shape[i]);
  }
  return s + "]";
}

}  // namespace

int64_t HostView::elements() const { return product(shape); }
uint64_t HostView::bytes() const { return uint64_t(elements()) * element_bytes(type); }
std::string HostView::describe() const { return dvs::describe(type, shape); }

ConstHostView::ConstHostView(const void* data_, ElementType type_, std::vector<int64_t> shape_)
    : data(data_), type(type_), shape(std::move(shape_)) {}
ConstHostView::ConstHostView(const HostView& view) : data(view.data), type(view.type), shape(view.shape) {}
int64_t ConstHostView::elements() const { return product(shape); }
uint64_t ConstHostView::bytes() const { return uint64_t(elements()) * element_bytes(type); }
std::string ConstHostView::describe() const { return dvs::describe(type, shape); }

int64_t DeviceBufferView::elements() const { return product(shape); }
uint64_t DeviceBufferView::bytes() const { return uint64_t(elements()) * element_bytes(type); }
std::string DeviceBufferView::describe() const { return dvs::describe(type, shape); }

std::string DeviceImageView::describe() const {
  const char* name = format == VK_FORMAT_R8G8B8A8_UNORM  ? "VK_FORMAT_R8G8B8A8_UNORM"
                     : format == VK_FORMAT_R8G8B8A8_SRGB ? "VK_FORMAT_R8G8B8A8_SRGB"
                     : format == VK_FORMAT_R32_SFLOAT    ? "VK_FORMAT_R32_SFLOAT"
                     : format == VK_FORMAT_UNDEFINED     ? "VK_FORMAT_UNDEFINED"
                                                         : nullptr;
  std::string s = name ? name : "VkFormat ";
  if (!name) s += std::to_string(int(format));
  s += ' ';
  s += std::to_string(width);
  s += 'x';
  s += std::to_string(height);
  return s;
}

}  // namespace dvs
