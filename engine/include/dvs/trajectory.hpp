// Camera paths as the public API: key poses placed by the user (the preview, an editor) become one pose per frame,
// written as the trajectory files `dvs run/render --trajectory` read (JSON, .glb), and any trajectory dvs
// understands (presets, .txt, .json, .gltf/.glb) loads back as poses.
//
// A Pose (dvs/scene.hpp) is T, the world-to-camera transform whose world is the SOURCE camera (OpenCV axes);
// T = identity is the input view. Every path dvs makes starts there (frame 0 is the conditioning frame).
#pragma once
#include <string>
#include <vector>

#include "dvs/api.hpp"
#include "dvs/scene.hpp"

namespace dvs {

struct KeyPose {
  int frame = 0;  // the frame index this key is pinned to (0 … frames−1)
  Pose pose;
};

// The per-frame path through `keys` (sorted by frame, distinct frames, each pose rigid). Between two keys the
// CAMERA moves: its orientation by quaternion slerp (shortest arc, constant angular speed) and its centre along
// the straight line, both linear in the frame index. A key's frame gets exactly that key's pose (the same
// doubles); frames before the first key hold the first key's pose and frames after the last hold the last's.
// Throws dvs::Error for an empty key list, a frame outside 0 … frames−1, unsorted or repeated frames, or a
// pose that is not rigid.
DVS_API std::vector<Pose> interpolate_path(const std::vector<KeyPose>& keys, int frames);

// Key frame indices for `count` keys spread over `frames` frames: round(j·(frames−1)/(count−1)), the first key
// on frame 0 and the last on frames−1 (one key: frame 0).
DVS_API std::vector<int> evenly_spaced_key_frames(int count, int frames);

// Writes {"convention": "world_to_camera", "axes": "opencv", "poses": [...]} (docs/file-formats.md) atomically.
// Numbers are written with full double precision: load_trajectory gives back the same doubles.
DVS_API void write_trajectory_json(const std::string& path, const std::vector<Pose>& poses,
                                   const std::string& description = "");

// Writes a binary glTF (.glb): an animated camera with one LINEAR keyframe per frame at i/fps seconds and the
// path as a line strip (the same writer as `dvs render`'s scene.glb, without a point cloud). glTF stores floats,
// and a glTF camera path is read relative to its first frame: load_trajectory gives back T_i·T_0⁻¹ to float
// precision (about 1e-6), which is the path itself when it starts at the input view (T_0 = identity).
// Throws dvs::Error for another extension than .glb.
DVS_API void write_trajectory_glb(const std::string& path, const std::vector<Pose>& poses, double fps = 30);

// Any trajectory `dvs render --trajectory` takes: a preset name ("loop1", "pan_left:30"), or a .txt, .json,
// .gltf or .glb file, as `frames` poses. `radius` is the orbit radius of the presets and the official files
// (PointCloudScene::orbit_radius()); JSON and glTF files do not use it. Errors name the file and the problem.
DVS_API std::vector<Pose> load_trajectory(const std::string& spec, int frames, double radius = 1.0);

}  // namespace dvs
