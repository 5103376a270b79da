// The user's camera: a position and an orientation in the SOURCE camera's frame (OpenCV: x right, y down,
// z forward), flown with keys (W/S forward/back, A/D left/right, Q/E up/down, along the camera's own axes) and
// mouse drags (horizontal: turn about the source camera's vertical axis, so the horizon stays level; vertical:
// tilt about the camera's own x axis). Its dvs::Pose is T = C⁻¹, what dvs renders and trajectory files hold.
#pragma once
#include <array>

#include "dvs/scene.hpp"

namespace preview {

class FlyCamera {
 public:
  // Back at the source camera (the input view): T = identity.
  void reset();
  // Moves by `step` scene units along the camera's axes: forward (+z), right (+x), down (+y).
  void move(double forward, double right, double down, double step);
  // Turns by the mouse motion, `radians_per_pixel` a pixel: dx > 0 turns right, dy > 0 (dragging down) looks down.
  void look(double dx, double dy, double radians_per_pixel);
  // Takes the camera of a pose (a rigid world-to-camera T), e.g. a frame of the path while scrubbing.
  void set_pose(const dvs::Pose& pose);
  dvs::Pose pose() const;

 private:
  std::array<double, 9> rotation_{1, 0, 0, 0, 1, 0, 0, 0, 1};  // camera-to-world, row-major
  std::array<double, 3> centre_{0, 0, 0};
};

}  // namespace preview
