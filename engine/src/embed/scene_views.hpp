// The memory views PointCloudScene takes (dvs/scene.hpp), checked against the shapes it expects, and its inputs
// converted as `dvs render` converts the same data read from files. Errors name the argument, the expected shape
// and what was given: "PointCloudScene: frame: expected u8 [H,W,3] or f32 [3,H,W], got f32[480x720]".
#pragma once
#include "dvs/views.hpp"
#include "io/depth.hpp"
#include "io/host_tensor.hpp"

namespace dvs::embed {

// The frame as f32 [1,3,H,W] in [−1,1]: f32 [3,H,W] as it is, u8 [H,W,3] RGB by the video reader's level rule
// (io/pixel_levels.hpp), so a frame in memory equals the same frame decoded from a file.
HostTensor scene_frame(const ConstHostView& frame);

// Depth f32 [H,W] (of the frame's height × width) as metric depth [1,H,W]: disparity converted as `dvs render`
// converts a one-frame depth file (depth_from_array), metric depth checked (> 0, finite).
HostTensor scene_depth(const ConstHostView& depth, int height, int width, DepthValues values);

// What a render writes into: f32 [3,H,W] (the render in [−1,1]) or u8 [H,W,4] (RGBA8).
enum class SceneImage { planar_f32, rgba8 };

SceneImage host_image_kind(const HostView& image, int height, int width);
// Whether a mask is asked for (data not null); when it is, it must be f32 [H,W].
bool host_mask_wanted(const HostView& mask, int height, int width);
SceneImage device_image_kind(const DeviceBufferView& image, int height, int width);
bool device_mask_wanted(const DeviceBufferView& mask, int height, int width);

}  // namespace dvs::embed
