// Pinhole intrinsics in the OpenCV convention: x right, y down, z forward (into the scene); a pixel (x, y)
// is the integer column / row index with NO +0.5 centre offset, exactly as the official code unprojects.
//   unproject: X = z · K⁻¹ (x, y, 1)ᵀ        project: (u, v) = (fx·X/Z + cx, fy·Y/Z + cy), depth Z
#pragma once
#include <glm/glm.hpp>

namespace dvs::geometry {

struct Intrinsics {
  double fx = 500, fy = 500, cx = 512, cy = 288;
  int width = 1024, height = 576;  // image size these intrinsics belong to

  // The official default: f = 500 px, c = (512, 288) at 1024×576, scaled to width × height
  // (fx, cx by width/1024; fy, cy by height/576).
  static Intrinsics official_default(int width, int height);
  // What dvs uses when no intrinsics are given (dvs render, dvs::CameraIntrinsics::dvs_default). The official
  // per-axis scaling is right for a squashed frame (squash = true) but not for a centre crop, which scales both
  // axes by one factor: then the 1024×576 frame is cropped to the working aspect and scaled to cover it, so
  // fx = fy = 500 · max(W/1024, H/576), centred.
  static Intrinsics dvs_default(int width, int height, bool squash);
  // The same camera seen at another image size (plain scaling of f and c, as above).
  Intrinsics scaled_to(int new_width, int new_height) const;
  // Throws dvs::Error when a value is not finite / positive or the size is empty.
  void validate() const;

  glm::dmat3 K() const;
  glm::dmat3 K_inv() const;
  glm::dvec3 unproject(double x, double y, double z) const;  // camera-space point at depth z
  glm::dvec3 project(const glm::dvec3& X) const;             // (u, v, Z); Z ≤ 0 means behind the camera
};

}  // namespace dvs::geometry
