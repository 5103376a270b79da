// A procedural RGB-D test scene with exact depth and exact novel views, for tests, benchmarks and demos.
//
// In the source camera's coordinates (OpenCV: x right, y down, z forward): a textured ground plane
// y = +2 (two units below the camera, so the official orbits, which move the camera by up to
// 5·sin 20° ≈ 1.7 vertically, stay above it), a textured back wall z = 6, and a textured floating box
// (side 1, centre y = 0.5, depth z = 3) that slides from x = −0.8 to x = +0.8 over the clip. Frames are ray-cast analytically, so render_synthetic(spec, T) is the exact view of the camera
// C_i = T_i⁻¹ for every frame — the ground truth for the splat renderer. Textures are smooth sinusoids so
// that resampling error stays small. Rays that hit nothing (only possible for cameras turned far away)
// get colour −1 and depth 0, with valid = 0.
#pragma once
#include "geometry/camera.hpp"
#include "geometry/trajectory.hpp"
#include "io/host_tensor.hpp"

namespace dvs::geometry {

struct SyntheticSceneSpec {
  int frames = 8, height = 96, width = 128;
  Intrinsics K = Intrinsics::official_default(128, 96);
};

struct RgbdClip {
  HostTensor rgb;    // [F,3,H,W] f32 in [−1,1]
  HostTensor depth;  // [F,H,W] f32, camera depth (z), 0 where nothing was hit
  HostTensor valid;  // [F,H,W] f32, 1 where a surface was hit
};

// The clip seen by the source camera (identity poses).
RgbdClip render_synthetic(const SyntheticSceneSpec& spec);
// The clip seen by the target camera of every frame (trajectory.frames() must equal spec.frames).
RgbdClip render_synthetic(const SyntheticSceneSpec& spec, const Trajectory& trajectory);

}  // namespace dvs::geometry
