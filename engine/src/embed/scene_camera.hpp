// The embedding API's camera (dvs/scene.hpp: CameraIntrinsics, row-major Pose) as the splat renderer's
// (geometry::Intrinsics, glm's column-major dmat4), checked, with errors that name the argument.
#pragma once
#include <glm/glm.hpp>

#include "dvs/scene.hpp"
#include "geometry/camera.hpp"

namespace dvs::embed {

// `K` for a frame of height × width: finite, positive focal lengths and the same size as the frame.
geometry::Intrinsics scene_intrinsics(const CameraIntrinsics& K, int height, int width);

// The pose's row-major T as glm's column-major matrix (T[col][row] = m[row·4 + col]). Refuses values that are not
// finite and a bottom row other than 0 0 0 1 (what a column-major matrix handed over untransposed looks like).
glm::dmat4 pose_matrix(const Pose& pose);

}  // namespace dvs::embed
