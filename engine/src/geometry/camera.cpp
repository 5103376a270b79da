#include "geometry/camera.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "dvs/error.hpp"

namespace dvs::geometry {

Intrinsics Intrinsics::official_default(int width, int height) {
  Intrinsics k;  // 1024×576 values
  return k.scaled_to(width, height);
}

Intrinsics Intrinsics::dvs_default(int width, int height, bool squash) {
  Intrinsics k = official_default(width, height);
  if (!squash) k.fx = k.fy = 500.0 * std::max(double(width) / 1024.0, double(height) / 576.0);
  return k;
}

Intrinsics Intrinsics::scaled_to(int new_width, int new_height) const {
  if (new_width <= 0 || new_height <= 0)
    throw Error("camera: image size must be positive, got " + std::to_string(new_height) + "x" +
                std::to_string(new_width) + " (HxW)");
  Intrinsics k = *this;
  double sx = double(new_width) / width, sy = double(new_height) / height;
  k.fx = fx * sx;
  k.cx = cx * sx;
  k.fy = fy * sy;
  k.cy = cy * sy;
  k.width = new_width;
  k.height = new_height;
  return k;
}

void Intrinsics::validate() const {
  auto bad = [](double v) { return !std::isfinite(v); };
  if (width <= 0 || height <= 0) throw Error("camera: image size must be positive");
  if (bad(fx) || bad(fy) || fx <= 0 || fy <= 0)
    throw Error("camera: focal lengths must be finite and > 0 (fx=" + std::to_string(fx) +
                ", fy=" + std::to_string(fy) + ")");
  if (bad(cx) || bad(cy)) throw Error("camera: principal point must be finite");
}

// GLM matrices are column-major: m[col][row].
glm::dmat3 Intrinsics::K() const {
  glm::dmat3 m(1.0);
  m[0][0] = fx;
  m[1][1] = fy;
  m[2][0] = cx;
  m[2][1] = cy;
  return m;
}

glm::dmat3 Intrinsics::K_inv() const {
  glm::dmat3 m(1.0);
  m[0][0] = 1.0 / fx;
  m[1][1] = 1.0 / fy;
  m[2][0] = -cx / fx;
  m[2][1] = -cy / fy;
  return m;
}

glm::dvec3 Intrinsics::unproject(double x, double y, double z) const {
  return z * glm::dvec3((x - cx) / fx, (y - cy) / fy, 1.0);
}

glm::dvec3 Intrinsics::project(const glm::dvec3& X) const {
  return {fx * X.x / X.z + cx, fy * X.y / X.z + cy, X.z};
}

}  // namespace dvs::geometry
