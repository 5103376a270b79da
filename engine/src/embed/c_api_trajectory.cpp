// dvs/dvs.h: camera paths (dvs/trajectory.hpp) from C: presets and files as poses, key poses interpolated, poses
// written as the files `dvs run --trajectory` reads. Poses are 16 row-major doubles each (dvs_scene_render's).
#include <cstring>

#include "dvs/trajectory.hpp"
#include "embed/c_api_guard.hpp"
#include "embed/c_api_options.hpp"

using namespace dvs::capi;

namespace {

// Checks that `doubles` is 16 per pose for `count` poses (the caller's buffer), naming the argument.
void check_pose_buffer(const void* poses, size_t doubles, int32_t count, const char* call, const char* name) {
  require(poses, call, name);
  check_size(count, call, "frames");
  if (doubles != size_t(count) * 16)
    throw dvs::UsageError(std::string(call) + ": pose_doubles is " + std::to_string(doubles) + " but " +
                          std::to_string(count) + " poses are " + std::to_string(size_t(count) * 16) + " doubles");
}

std::vector<dvs::Pose> poses_in(const double* poses, int32_t count) {
  std::vector<dvs::Pose> list(static_cast<size_t>(count));
  for (int32_t i = 0; i < count; ++i) std::memcpy(list[size_t(i)].m.data(), poses + 16 * i, 16 * sizeof(double));
  return list;
}

void poses_out(const std::vector<dvs::Pose>& list, double* poses) {
  for (size_t i = 0; i < list.size(); ++i) std::memcpy(poses + 16 * i, list[i].m.data(), 16 * sizeof(double));
}

}  // namespace

extern "C" {

dvs_status dvs_trajectory_load(const char* spec, int32_t frames, double radius, double* poses, size_t pose_doubles) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_trajectory_load";
    require(spec, call, "spec");
    check_pose_buffer(poses, pose_doubles, frames, call, "poses");
    if (!(radius > 0))
      throw dvs::UsageError(std::string(call) + ": radius must be > 0 (dvs_scene_orbit_radius gives the presets' unit), got " +
                            std::to_string(radius));
    use_c_names_in_default_log();  // a trajectory file's warning goes where the C program's other warnings go
    const std::vector<dvs::Pose> list = dvs::load_trajectory(spec, frames, radius);
    if (list.size() != size_t(frames))
      throw dvs::Error(std::string(call) + ": " + spec + " gave " + std::to_string(list.size()) + " poses for " +
                       std::to_string(frames) + " frames");
    poses_out(list, poses);
  });
}

dvs_status dvs_trajectory_interpolate(const int32_t* key_frames, const double* key_poses, int32_t key_count,
                                      int32_t frames, double* poses, size_t pose_doubles) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_trajectory_interpolate";
    require(key_frames, call, "key_frames");
    require(key_poses, call, "key_poses");
    check_size(key_count, call, "key_count");
    check_pose_buffer(poses, pose_doubles, frames, call, "poses");
    std::vector<dvs::KeyPose> keys(static_cast<size_t>(key_count));
    for (int32_t i = 0; i < key_count; ++i) {
      keys[size_t(i)].frame = key_frames[i];
      std::memcpy(keys[size_t(i)].pose.m.data(), key_poses + 16 * i, 16 * sizeof(double));
    }
    poses_out(dvs::interpolate_path(keys, frames), poses);
  });
}

dvs_status dvs_trajectory_write_json(const char* path, const double* poses, int32_t count, const char* description) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_trajectory_write_json";
    require(path, call, "path");
    require(poses, call, "poses");
    check_size(count, call, "count");
    dvs::write_trajectory_json(path, poses_in(poses, count), description ? description : "");
  });
}

dvs_status dvs_trajectory_write_glb(const char* path, const double* poses, int32_t count, double fps) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_trajectory_write_glb";
    require(path, call, "path");
    require(poses, call, "poses");
    check_size(count, call, "count");
    if (!(fps > 0)) throw dvs::UsageError(std::string(call) + ": fps must be > 0, got " + std::to_string(fps));
    dvs::write_trajectory_glb(path, poses_in(poses, count), fps);
  });
}

}  // extern "C"
