// glTF 2.0 (tinygltf): camera paths drawn in Blender or any DCC tool, and export of a trajectory plus a
// point cloud as .glb to look at in any glTF viewer.
//
// Import: the animated camera node's global transform (node TRS keyframes, LINEAR — slerp for rotations —
// or STEP interpolation, parents included) is sampled at `frames` times. A glTF camera looks down its
// local −Z with +Y up; it is converted to OpenCV (x right, y down, z forward): C_cv = C_gltf · diag(1,−1,−1).
// Frame 0's camera is the source camera: T_i = C_cv(t_i)⁻¹ · C_cv(t_0), so the glTF world frame and units are
// free (translations are multiplied by `translation_scale` to match the depth units).
//
// Export: world = the source camera (OpenCV) with y and z flipped so the scene stands upright in viewers
// (glTF is y-up); nodes "point_cloud" (POINTS with COLOR_0), "camera" (perspective, animated with one
// LINEAR keyframe per frame at i / fps seconds) and "camera_path" (LINE_STRIP of the camera centres).
// Reading an exported file back with the same frame count gives the same transforms.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "geometry/camera.hpp"
#include "geometry/trajectory.hpp"

namespace dvs::geometry {

struct GltfCameraOptions {
  int frames = 0;                 // number of frames to sample (required, ≥ 1)
  std::string node;               // node name; empty: the first node with a camera, else the first animated node
  double fps = 0;                 // 0: frames spread uniformly over the animation's time range; else frame i at t0 + i/fps
  double translation_scale = 1;   // glTF units → depth units
};

// Errors name the file and the offending node / animation / accessor.
Trajectory read_gltf_trajectory(const std::filesystem::path& path, const GltfCameraOptions& options);

struct PointCloud {
  std::vector<glm::vec3> positions;  // source-camera coordinates (OpenCV)
  std::vector<glm::vec3> colors;     // linear 0..1
};

// Frame `frame` of rgb [F,3,H,W] in [−1,1] and depth [F,H,W] lifted with X = z·K⁻¹(x, y, 1), every `stride`-th
// pixel in x and y; pixels with a non-finite or non-positive depth are skipped.
PointCloud point_cloud_from_rgbd(const float* rgb_frame, const float* depth_frame, int height, int width,
                                 const Intrinsics& K, int stride = 1);

struct GlbExportOptions {
  double fps = 30;
  const Intrinsics* intrinsics = nullptr;  // sets the camera's field of view; default 60° vertical
  // Points farther than this multiple of the cloud's median depth are left out (0 keeps all): depth from
  // disparity puts the sky at 10⁴ units, which would make a viewer's "fit to view" show a dot.
  double far_clip_over_median = 8;
};

// The points of `cloud` whose depth (z) is at most `ratio` × the median depth (all of them for ratio ≤ 0).
PointCloud clip_far_points(const PointCloud& cloud, double ratio);

// Writes a binary glTF atomically (temporary file + rename) that passes the Khronos glTF validator. `cloud`
// may be null. The perspective camera has znear 0.01 and a finite zfar beyond every point and camera
// centre (glTF 2.0 forbids zfar = 0; an absent zfar means an infinite projection, which some viewers
// mishandle).
void write_trajectory_glb(const std::filesystem::path& path, const Trajectory& trajectory, const PointCloud* cloud,
                          const GlbExportOptions& options = {});

}  // namespace dvs::geometry
