// dvs/trajectory.hpp over geometry's trajectory readers and writers: key poses → per-frame path, files ↔ poses.
#include "dvs/trajectory.hpp"

#include <cmath>
#include <filesystem>
#include <string>

#include <glm/gtc/quaternion.hpp>

#include "dvs/error.hpp"
#include "geometry/trajectory.hpp"
#include "geometry/trajectory_gltf.hpp"
#include "geometry/trajectory_json.hpp"
#include "io/library_log.hpp"

namespace dvs {

namespace {

// Pose::m is row-major; glm matrices are indexed [column][row].
glm::dmat4 to_glm(const Pose& p) {
  glm::dmat4 m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) m[c][r] = p.m[size_t(r * 4 + c)];
  return m;
}

Pose from_glm(const glm::dmat4& m) {
  Pose p;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) p.m[size_t(r * 4 + c)] = m[c][r];
  return p;
}

// A rotation part off by more than this from orthonormal is a caller's mistake (scale, shear), not rounding.
constexpr double kRigidTolerance = 1e-6;

void check_rigid(const Pose& p, const std::string& what) {
  const glm::dmat4 m = to_glm(p);
  const glm::dmat3 r(m);
  const glm::dmat3 rtr = glm::transpose(r) * r;
  double worst = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) worst = std::max(worst, std::abs(rtr[i][j] - (i == j ? 1.0 : 0.0)));
  const bool last_row = m[0][3] == 0 && m[1][3] == 0 && m[2][3] == 0 && m[3][3] == 1;
  if (!(worst <= kRigidTolerance) || !(glm::determinant(r) > 0) || !last_row)
    throw Error(what + " is not a rigid transform (a rotation and a translation with last row 0 0 0 1): "
                "build it from a rotation matrix and a translation", ErrorKind::invalid_argument);
}

// The camera of T: orientation (camera-to-world rotation Rᵀ) and centre −Rᵀt.
struct Camera {
  glm::dquat orientation;
  glm::dvec3 centre;
};

Camera camera_of(const Pose& p) {
  const glm::dmat4 t = to_glm(p);
  const glm::dmat3 rt = glm::transpose(glm::dmat3(t));
  return {glm::normalize(glm::quat_cast(rt)), -(rt * glm::dvec3(t[3]))};
}

Pose pose_of(const Camera& c) {
  const glm::dmat3 r = glm::transpose(glm::mat3_cast(c.orientation));
  glm::dmat4 t(r);
  t[3] = glm::dvec4(-(r * c.centre), 1.0);
  return from_glm(t);
}

geometry::Trajectory to_trajectory(const std::vector<Pose>& poses, const std::string& description) {
  geometry::Trajectory t;
  t.description = description;
  for (const Pose& p : poses) t.transforms.push_back(to_glm(p));
  return t;
}

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& ch : ext) ch = char(std::tolower(static_cast<unsigned char>(ch)));
  return ext;
}

}  // namespace

std::vector<Pose> interpolate_path(const std::vector<KeyPose>& keys, int frames) {
  if (frames < 1)
    throw Error("interpolate_path: the frame count must be at least 1 (got " + std::to_string(frames) + ")",
                ErrorKind::invalid_argument);
  if (keys.empty()) throw Error("interpolate_path: no key poses (place at least one)", ErrorKind::invalid_argument);
  for (size_t k = 0; k < keys.size(); ++k) {
    const std::string name = "key pose " + std::to_string(k) + " (frame " + std::to_string(keys[k].frame) + ")";
    if (keys[k].frame < 0 || keys[k].frame >= frames)
      throw Error("interpolate_path: " + name + " is outside the path's frames 0.." + std::to_string(frames - 1),
                  ErrorKind::invalid_argument);
    if (k > 0 && keys[k].frame <= keys[k - 1].frame)
      throw Error("interpolate_path: " + name + " does not come after key pose " + std::to_string(k - 1) +
                  " (frame " + std::to_string(keys[k - 1].frame) + "): keys must be sorted by distinct frames",
                  ErrorKind::invalid_argument);
    check_rigid(keys[k].pose, "interpolate_path: " + name);
  }
  std::vector<Pose> path(static_cast<size_t>(frames));
  for (int f = 0; f < frames; ++f) {
    if (f <= keys.front().frame) {
      path[size_t(f)] = keys.front().pose;
      continue;
    }
    if (f >= keys.back().frame) {
      path[size_t(f)] = keys.back().pose;
      continue;
    }
    size_t b = 1;
    while (keys[b].frame < f) ++b;
    const KeyPose& hi = keys[b];
    const KeyPose& lo = keys[b - 1];
    if (f == hi.frame) {  // exactly the key, not its quaternion round trip
      path[size_t(f)] = hi.pose;
      continue;
    }
    const double s = double(f - lo.frame) / double(hi.frame - lo.frame);
    const Camera a = camera_of(lo.pose), c = camera_of(hi.pose);
    path[size_t(f)] = pose_of({glm::slerp(a.orientation, c.orientation, s), a.centre + s * (c.centre - a.centre)});
  }
  return path;
}

std::vector<int> evenly_spaced_key_frames(int count, int frames) {
  if (count < 1 || frames < count)
    throw Error("evenly_spaced_key_frames: " + std::to_string(count) + " keys do not fit in " +
                std::to_string(frames) + " frames (need 1 ≤ keys ≤ frames)", ErrorKind::invalid_argument);
  std::vector<int> out(size_t(count), 0);
  for (int j = 1; j < count; ++j) out[size_t(j)] = int(std::lround(double(j) * (frames - 1) / (count - 1)));
  return out;
}

void write_trajectory_json(const std::string& path, const std::vector<Pose>& poses, const std::string& description) {
  if (poses.empty()) throw Error(path + ": cannot write an empty trajectory (no poses)", ErrorKind::invalid_argument);
  for (size_t i = 0; i < poses.size(); ++i) check_rigid(poses[i], path + ": pose " + std::to_string(i));
  geometry::write_trajectory_json(path, to_trajectory(poses, description));
}

void write_trajectory_glb(const std::string& path, const std::vector<Pose>& poses, double fps) {
  if (lower_extension(path) != ".glb")
    throw Error(path + ": a glTF trajectory is written as binary glTF: name the file *.glb",
                ErrorKind::invalid_argument);
  if (poses.empty()) throw Error(path + ": cannot write an empty trajectory (no poses)", ErrorKind::invalid_argument);
  for (size_t i = 0; i < poses.size(); ++i) check_rigid(poses[i], path + ": pose " + std::to_string(i));
  geometry::GlbExportOptions options;
  options.fps = fps;
  geometry::write_trajectory_glb(path, to_trajectory(poses, "dvs::write_trajectory_glb"), nullptr, options);
}

std::vector<Pose> load_trajectory(const std::string& spec, int frames, double radius) {
  const geometry::Trajectory t = geometry::load_trajectory(spec, frames, radius);
  for (const std::string& w : t.warnings) log_warning(w);  // e.g. an official .txt whose lines differ in length
  std::vector<Pose> out;
  out.reserve(t.transforms.size());
  for (const auto& m : t.transforms) out.push_back(from_glm(m));
  return out;
}

}  // namespace dvs
