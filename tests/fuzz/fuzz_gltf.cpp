// glTF camera import (geometry/trajectory_gltf.hpp through load_trajectory): a binary .glb when the input starts
// with glTF's magic, else a .gltf JSON file; the camera node, its parents, the animation samplers and accessors.
#include <cstring>

#include "dvs/error.hpp"
#include "geometry/trajectory.hpp"
#include "harness_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const bool binary = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  const auto file = dvs::fuzz::write_scratch(binary ? "camera.glb" : "camera.gltf", dvs::fuzz::as_text(data, size));
  try {
    (void)dvs::geometry::load_trajectory(file.string(), 4, 1.0);
  } catch (const dvs::Error&) {
  }
  return 0;
}
