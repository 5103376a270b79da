// Checks and conversions of PointCloudScene's memory views (embed/scene_views.hpp).
#include "embed/scene_views.hpp"

#include <cstring>
#include <string>

#include "dvs/error.hpp"
#include "io/pixel_levels.hpp"

namespace dvs::embed {
namespace {

std::string shape_text(ElementType type, const std::vector<int64_t>& shape) {
  HostView v;
  v.type = type;
  v.shape = shape;
  return v.describe();
}

bool is(ElementType type, const std::vector<int64_t>& shape, ElementType want_type, const std::vector<int64_t>& want) {
  return type == want_type && shape == want;
}

[[noreturn]] void wrong(const char* arg, const std::string& expected, ElementType type, const std::vector<int64_t>& shape) {
  throw Error(std::string("PointCloudScene: ") + arg + ": expected " + expected + ", got " + shape_text(type, shape),
              ErrorKind::invalid_argument);
}

std::string hw(const char* prefix, int height, int width, const char* suffix) {
  return std::string(prefix) + std::to_string(height) + "," + std::to_string(width) + suffix;
}

SceneImage image_kind(const char* arg, ElementType type, const std::vector<int64_t>& shape, int height, int width) {
  if (is(type, shape, ElementType::f32, {3, height, width})) return SceneImage::planar_f32;
  if (is(type, shape, ElementType::u8, {height, width, 4})) return SceneImage::rgba8;
  wrong(arg, hw("f32 [3,", height, width, "]") + hw(" or u8 [", height, width, ",4]") + " (the scene's size)", type,
        shape);
}

void check_mask(const char* arg, ElementType type, const std::vector<int64_t>& shape, int height, int width) {
  if (!is(type, shape, ElementType::f32, {height, width})) wrong(arg, hw("f32 [", height, width, "]"), type, shape);
}

void need_data(const char* arg, const ConstHostView& v) {
  if (!v.data)
    throw Error(std::string("PointCloudScene: ") + arg + ": the view's data pointer is null", ErrorKind::invalid_argument);
}

}  // namespace

HostTensor scene_frame(const ConstHostView& frame) {
  const auto& s = frame.shape;
  const bool rgb8 = frame.type == ElementType::u8 && s.size() == 3 && s[2] == 3 && s[0] > 0 && s[1] > 0;
  const bool planar = frame.type == ElementType::f32 && s.size() == 3 && s[0] == 3 && s[1] > 0 && s[2] > 0;
  if (!rgb8 && !planar) wrong("frame", "u8 [H,W,3] or f32 [3,H,W]", frame.type, s);
  need_data("frame", frame);
  const int64_t H = rgb8 ? s[0] : s[1], W = rgb8 ? s[1] : s[2], plane = H * W;
  HostTensor out({1, 3, H, W}, DType::f32);
  if (planar) {
    std::memcpy(out.data.data(), frame.data, size_t(frame.bytes()));
    return out;
  }
  const auto* rgb = static_cast<const uint8_t*>(frame.data);
  float* dst = out.as<float>();
  for (int64_t i = 0; i < plane; ++i)
    for (int64_t c = 0; c < 3; ++c) dst[c * plane + i] = level_to_unit(rgb[i * 3 + c]);
  return out;
}

HostTensor scene_depth(const ConstHostView& depth, int height, int width, DepthValues values) {
  if (!is(depth.type, depth.shape, ElementType::f32, {height, width}))
    wrong("depth", hw("f32 [", height, width, "] (the frame's size)"), depth.type, depth.shape);
  need_data("depth", depth);
  HostTensor d({1, height, width}, DType::f32);
  std::memcpy(d.data.data(), depth.data, size_t(depth.bytes()));
  DepthOptions o;
  o.values = values;
  return depth_from_array(d, "PointCloudScene: depth", o);
}

SceneImage host_image_kind(const HostView& image, int height, int width) {
  const SceneImage k = image_kind("image", image.type, image.shape, height, width);
  need_data("image", image);
  return k;
}

bool host_mask_wanted(const HostView& mask, int height, int width) {
  if (!mask.data) return false;
  check_mask("mask", mask.type, mask.shape, height, width);
  return true;
}

SceneImage device_image_kind(const DeviceBufferView& image, int height, int width) {
  if (image.buffer == VK_NULL_HANDLE)
    throw Error("PointCloudScene: image: the device view's buffer is VK_NULL_HANDLE", ErrorKind::invalid_argument);
  if (image.offset % 4)
    throw Error("PointCloudScene: image: the device view's offset must be a multiple of 4", ErrorKind::invalid_argument);
  return image_kind("image", image.type, image.shape, height, width);
}

bool device_mask_wanted(const DeviceBufferView& mask, int height, int width) {
  if (mask.buffer == VK_NULL_HANDLE) return false;
  if (mask.offset % 4)
    throw Error("PointCloudScene: mask: the device view's offset must be a multiple of 4", ErrorKind::invalid_argument);
  check_mask("mask", mask.type, mask.shape, height, width);
  return true;
}

}  // namespace dvs::embed
