// What the argument checks of the embedding calls need of an application's view, host or device, so one check
// serves both forms: its name, element type, shape, whether it is given, its description, and why it is not given.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include "dvs/views.hpp"

namespace dvs::embed {

struct ViewFacts {
  std::string name;  // "ClipView::frames", "ClipResultDeviceViews::latent", ...
  ElementType type = ElementType::f32;
  std::vector<int64_t> shape;
  bool given = false;
  std::string text;     // "u8[9x64x64x3]"
  std::string missing;  // why it is not given: "the view's data pointer is null", "... buffer is VK_NULL_HANDLE"
};

inline ViewFacts facts(std::string name, const ConstHostView& v,
                       std::string missing = "the view's data pointer is null") {
  return {std::move(name), v.type, v.shape, v.data != nullptr, v.describe(), std::move(missing)};
}
inline ViewFacts facts(std::string name, const DeviceBufferView& v,
                       std::string missing = "the view's buffer is VK_NULL_HANDLE") {
  return {std::move(name), v.type, v.shape, v.buffer != VK_NULL_HANDLE, v.describe(), std::move(missing)};
}

}  // namespace dvs::embed
