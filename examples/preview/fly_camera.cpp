#include "fly_camera.hpp"

#include <cmath>

namespace preview {

namespace {

using Mat3 = std::array<double, 9>;

Mat3 multiply(const Mat3& a, const Mat3& b) {
  Mat3 c{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) c[size_t(i * 3 + j)] += a[size_t(i * 3 + k)] * b[size_t(k * 3 + j)];
  return c;
}

// Rotations in OpenCV axes, as in dvs's presets: Ry(+a) turns the camera right, Rx(+a) turns it up.
Mat3 rotation_y(double a) { return {std::cos(a), 0, std::sin(a), 0, 1, 0, -std::sin(a), 0, std::cos(a)}; }
Mat3 rotation_x(double a) { return {1, 0, 0, 0, std::cos(a), -std::sin(a), 0, std::sin(a), std::cos(a)}; }

}  // namespace

void FlyCamera::reset() { *this = FlyCamera(); }

void FlyCamera::move(double forward, double right, double down, double step) {
  for (int i = 0; i < 3; ++i)
    centre_[size_t(i)] += step * (rotation_[size_t(i * 3 + 0)] * right + rotation_[size_t(i * 3 + 1)] * down +
                                  rotation_[size_t(i * 3 + 2)] * forward);
}

void FlyCamera::look(double dx, double dy, double radians_per_pixel) {
  // Turn about the world's vertical first (left-multiplied), then tilt about the camera's x (right-multiplied).
  rotation_ = multiply(multiply(rotation_y(dx * radians_per_pixel), rotation_), rotation_x(-dy * radians_per_pixel));
}

void FlyCamera::set_pose(const dvs::Pose& pose) {
  // T = [Rᵀ | −Rᵀc]: R = (T's rotation)ᵀ, c = −R·t.
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) rotation_[size_t(i * 3 + j)] = pose.m[size_t(j * 4 + i)];
  for (int i = 0; i < 3; ++i) {
    double c = 0;
    for (int j = 0; j < 3; ++j) c -= rotation_[size_t(i * 3 + j)] * pose.m[size_t(j * 4 + 3)];
    centre_[size_t(i)] = c;
  }
}

dvs::Pose FlyCamera::pose() const {
  dvs::Pose p;
  for (int i = 0; i < 3; ++i) {
    double t = 0;
    for (int j = 0; j < 3; ++j) {
      p.m[size_t(i * 4 + j)] = rotation_[size_t(j * 3 + i)];
      t -= rotation_[size_t(j * 3 + i)] * centre_[size_t(j)];
    }
    p.m[size_t(i * 4 + 3)] = t;
  }
  return p;
}

}  // namespace preview
