// Trajectories as JSON: per-frame 4×4 matrices (or rotation + translation).
//
//   {
//     "convention": "world_to_camera" | "camera_to_world",      required
//     "axes": "opencv" | "opengl",                              optional, default "opencv"
//     "relative_to_first": false,                               optional
//     "poses": [ M_0, M_1, ... ]                                required, one per frame
//   }
// Each pose is a 4×4 matrix as 4 rows of 4 numbers, 16 numbers in row-major order, or
// {"R": 3 rows of 3, "t": [x, y, z]} (meaning [R | t; 0 0 0 1]). The matrices must be rigid.
// "world" is the source camera's coordinate frame (OpenCV: x right, y down, z forward), so a
// world_to_camera matrix is exactly Trajectory::transforms[i] and a camera_to_world matrix is its inverse.
// With "relative_to_first": true the world is arbitrary and frame 0's camera is the source camera:
// T_i = W_i · W_0⁻¹. With "axes": "opengl" the cameras (and the world, when it is the source camera) use
// x right, y up, z backward; they are converted to OpenCV.
#pragma once
#include <filesystem>
#include <string>

#include "geometry/trajectory.hpp"

namespace dvs::geometry {

// Errors name the file and the field (and the JSON line/column for syntax errors).
Trajectory parse_trajectory_json(const std::string& text, const std::string& name);
Trajectory read_trajectory_json(const std::filesystem::path& path);

// Writes {"convention": "world_to_camera", "axes": "opencv", "poses": [...4 rows...], "description": ...}
// atomically (temporary file + rename). read_trajectory_json gives back the same transforms.
std::string trajectory_to_json(const Trajectory& t);
void write_trajectory_json(const std::filesystem::path& path, const Trajectory& t);

}  // namespace dvs::geometry
