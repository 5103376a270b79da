// The splat render as a real-time call: a point cloud built once from one frame and its depth, rendered from any
// camera, as often as the application likes (a camera-path preview, an AR overlay). The same shaders and the same
// math as `dvs render` (soft bilinear splat by default), so a pose rendered here equals `dvs render`'s frame at
// that pose.
//
// Cameras use the OpenCV convention (x right, y down, z forward; pixel (x, y) is the integer column/row, no +0.5).
// A Pose is T, the 4×4 world-to-camera transform whose world is the SOURCE camera: T = identity renders the input
// view; a target camera with pose C (camera-to-world) has T = C⁻¹. This is what a trajectory JSON with
// "convention": "world_to_camera", "axes": "opencv" holds per frame (docs/file-formats.md).
#pragma once
#include <array>
#include <cstdint>
#include <memory>

#include "dvs/api.hpp"
#include "dvs/context.hpp"
#include "dvs/views.hpp"

namespace dvs {

struct CameraIntrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pixels of width × height
  int width = 0, height = 0;
  // What `dvs render` uses when --intrinsics is not given: f = 500 px at 1024×576 with the frame centre-cropped
  // to the working aspect (square pixels, fx = fy = 500·max(W/1024, H/576)); squash = the official per-axis scaling.
  DVS_API static CameraIntrinsics dvs_default(int width, int height, bool squash = false);
};

struct Pose {
  std::array<double, 16> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  // row-major T (world-to-camera)
};

struct SceneOptions {
  bool depth_is_disparity = true;  // depth holds disparity (Video-Depth-Anything, dvs depth) as `dvs render` reads it
  bool hard_points = false;        // z-buffer point splat instead of the soft bilinear splat (dvs render --points)
};

class DVS_API PointCloudScene {
 public:
  // frame: u8 [H,W,3] RGB (what a video decoder gives) or f32 [3,H,W] RGB in [−1,1]; depth: f32 [H,W] (disparity,
  // converted exactly as `dvs render` converts a one-frame depth file, or metric depth). Uploaded once.
  PointCloudScene(Context& ctx, const ConstHostView& frame, const ConstHostView& depth,
                  const CameraIntrinsics& intrinsics, const SceneOptions& options = {});
  // The same from the application's device buffers (dvs/views.hpp; TRANSFER_SRC usage), with the same shapes and
  // the same conversions, so the scene equals the one built from the same values in host memory. The values are
  // copied on the device and the call returns when the scene is built (it waits: order the application's writes
  // before it with Context::wait_before_next, or finish them).
  PointCloudScene(Context& ctx, const DeviceBufferView& frame, const DeviceBufferView& depth,
                  const CameraIntrinsics& intrinsics, const SceneOptions& options = {});
  ~PointCloudScene();
  PointCloudScene(const PointCloudScene&) = delete;
  PointCloudScene& operator=(const PointCloudScene&) = delete;

  int width() const;
  int height() const;
  // The official orbit radius of this frame (min(centre depth, 5)): the unit of dolly/truck presets.
  double orbit_radius() const;
  // The camera-space depth at the centre pixel (after the disparity conversion).
  double centre_depth() const;

  // Renders the scene from `pose` into host memory and returns when done. image: f32 [3,H,W] in [−1,1] (holes −1)
  // or u8 [H,W,4] RGBA (alpha 255 where visible, holes black with alpha 0); mask (optional, data may be null): f32
  // [H,W], 1 = visible.
  void render(const Pose& pose, const HostView& image, const HostView& mask = {});
  // The same into application buffers (image f32 [3,H,W] or u8 [H,W,4], mask f32 [H,W] or no buffer). Returns the
  // timeline ticket of the render's last submission (Context::wait, or a wait on Context::timeline() in the
  // application's own submission): the call waits for nothing but the previous render of this scene, whose
  // buffers it reuses (on the host, only if that has not finished yet). The views must stay valid until the
  // ticket is reached.
  uint64_t render(const Pose& pose, const DeviceBufferView& image, const DeviceBufferView& mask = {});
  // The same into application images (dvs/views.hpp): image VK_FORMAT_R8G8B8A8_UNORM (RGBA as the u8 render),
  // mask VK_FORMAT_R32_SFLOAT (1 = visible) or VK_FORMAT_R8G8B8A8_UNORM (opaque white where visible, opaque black
  // elsewhere: ready to draw) or none (image VK_NULL_HANDLE), both width × height of the scene. Each is moved
  // from its `layout` to its `final_layout` in the same submission as the copy.
  uint64_t render(const Pose& pose, const DeviceImageView& image, const DeviceImageView& mask = {});

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dvs
