// dvs/scene.hpp's camera types: CameraIntrinsics::dvs_default and their conversion for the splat renderer.
#include "embed/scene_camera.hpp"

#include <cmath>
#include <cstdio>
#include <string>

#include "dvs/error.hpp"

namespace dvs {

// The one default `dvs render` uses too (geometry::Intrinsics::dvs_default), so a scene and the program agree.
CameraIntrinsics CameraIntrinsics::dvs_default(int width, int height, bool squash) {
  const geometry::Intrinsics k = geometry::Intrinsics::dvs_default(width, height, squash);
  return CameraIntrinsics{k.fx, k.fy, k.cx, k.cy, k.width, k.height};
}

namespace embed {
namespace {
std::string number(double v) {
  char s[32];
  std::snprintf(s, sizeof s, "%.9g", v);
  return s;
}
}  // namespace

geometry::Intrinsics scene_intrinsics(const CameraIntrinsics& K, int height, int width) {
  if (K.width != width || K.height != height)
    throw Error("PointCloudScene: intrinsics: they are for " + std::to_string(K.height) + "x" + std::to_string(K.width) +
                " (HxW) but the frame is " + std::to_string(height) + "x" + std::to_string(width) +
                "; give intrinsics of the frame's size (CameraIntrinsics::dvs_default(" + std::to_string(width) + ", " +
                std::to_string(height) + "), or scale fx, cx by the width and fy, cy by the height)",
                ErrorKind::invalid_argument);
  geometry::Intrinsics k;
  k.fx = K.fx, k.fy = K.fy, k.cx = K.cx, k.cy = K.cy, k.width = K.width, k.height = K.height;
  try {
    k.validate();
  } catch (const Error& e) {
    throw Error("PointCloudScene: intrinsics: " + std::string(e.what()), ErrorKind::invalid_argument);
  }
  return k;
}

glm::dmat4 pose_matrix(const Pose& pose) {
  glm::dmat4 T(1.0);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      const double v = pose.m[size_t(r * 4 + c)];
      if (!std::isfinite(v))
        throw Error("PointCloudScene: pose: element (" + std::to_string(r) + ", " + std::to_string(c) +
                    ") is not finite",
                    ErrorKind::invalid_argument);
      T[c][r] = v;
    }
  if (pose.m[12] != 0 || pose.m[13] != 0 || pose.m[14] != 0 || pose.m[15] != 1)
    throw Error("PointCloudScene: pose: the bottom row must be 0 0 0 1, got " + number(pose.m[12]) + " " +
                number(pose.m[13]) + " " + number(pose.m[14]) + " " + number(pose.m[15]) +
                ". Pose::m is the row-major world-to-camera transform (translation in m[3], m[7], m[11]); a "
                "column-major matrix (OpenGL, glm) must be transposed first",
                ErrorKind::invalid_argument);
  return T;
}

}  // namespace embed
}  // namespace dvs
