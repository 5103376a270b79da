// Camera trajectories as per-frame rigid transforms, in the OpenCV camera convention (x right, y down,
// z forward).
//
// Trajectory::transforms[i] = T_i, the 4×4 transform applied to frame i's points expressed in the SOURCE
// camera's coordinates; the result is in the TARGET camera's coordinates (a world-to-camera matrix whose
// world is the source camera). T_i = identity renders the input view. If C_i is the target camera's pose
// (camera-to-world, world = source camera), T_i = C_i⁻¹.
//
// Sources of trajectories:
//  (a) the official three-line files (line 0: θ° about x, line 1: φ° about y, line 2: r × radius), with the
//      six files shipped by the authors built in as presets with their exact 49-frame tables;
//  (b) ten canonical presets with a magnitude (see canonical_preset below);
//  (c) JSON per-frame matrices (trajectory_json.hpp);  (d) glTF camera animations (trajectory_gltf.hpp).
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include <glm/glm.hpp>

namespace dvs::geometry {

struct Trajectory {
  std::vector<glm::dmat4> transforms;  // T_i, see above
  std::string description;             // where it came from, for logs and the poses JSON
  // What the user must be told whatever the progress mode (the renderer prints each on stderr as
  // "dvs: warning: ..."): e.g. a .txt file whose lines hold different numbers of values.
  std::vector<std::string> warnings;
  int frames() const { return int(transforms.size()); }
};

// ---- (a) official three-line files -------------------------------------------------------------------
// Per-frame (or per-knot) values: θ (degrees, rotation about the camera x axis), φ (degrees, about y),
// r (dolly, multiplied by the radius).
struct OrbitAngles {
  std::vector<double> theta_deg, phi_deg, r;
  int lines[3] = {0, 0, 0};  // the file's line number of each list (0: not from a file)
};

// Parses the three whitespace-separated lists. Errors name the file and the line.
OrbitAngles parse_official_trajectory(const std::string& text, const std::string& name);
// A binary file is refused as not text (trajectory_text.hpp).
OrbitAngles read_official_trajectory(const std::filesystem::path& path);

// How many knots each line holds, for the trajectory's description: "9 knots per line", or each count when the
// lines differ (allowed, as in the authors' own files: each line is interpolated over the clip on its own).
std::string knot_counts(const OrbitAngles& knots);
// For a file whose lines differ in length: the warning naming the file, its line numbers and counts, and what dvs
// does with them (docs/file-formats.md); "" when the lines are equally long.
std::string unequal_lines_warning(const OrbitAngles& knots, const std::string& name);

// Resamples each list to `frames` values at linspace(0,1,frames) against knots at linspace(0,1,len):
// linear for len ≤ 3 (exactly the official interp1d); for len > 3 a NATURAL CUBIC INTERPOLATING spline
// through the knots. The official code uses scipy's UnivariateSpline(k=3, s=len) smoothing spline here,
// which does not pass through the knots (e.g. loop1 θ peaks at 14.18 instead of 15), so user files with > 3
// knots give a similar but not identical path; the six shipped files are exact through the presets.
// First and last values are the first and last knots (as the official code forces them).
OrbitAngles interpolate_official(const OrbitAngles& knots, int frames);

// The six official trajectories: loop1 loop2 loop3 loop4 oscillating_wave wave1. For 49 frames these are
// the exact tables; for another frame count the 49-frame table is resampled linearly (the official code
// would refit its spline at the other count; the difference is below 0.1° for these smooth paths).
const std::vector<std::string>& official_preset_names();
bool is_official_preset(const std::string& name);
OrbitAngles official_preset_angles(const std::string& name, int frames);

// radius = min(centre depth of frame 0 × radius_scale, 5): the official pivot distance. The centre pixel is
// (row H/2, col W/2) of frame 0 at the working size (row 288, col 512 at 576×1024).
double official_radius(double centre_depth, double radius_scale = 1.0);

// Official pose construction (docs/design.md §6.2), in closed form:
//   T = [M | (0,0,R)ᵀ − M·(0,0,R(1+r))ᵀ],  M = Ry(φ)·Rx(θ),
//   Rx(θ) = [[1,0,0],[0,c,−s],[0,s,c]],  Ry(φ) = [[c,0,s],[0,1,0],[−s,0,c]]
// i.e. an orbit by M about the pivot (0,0,R) plus a shift of −r·R along z: with M = I a point's depth becomes
// z − r·R, so r > 0 brings the scene closer (the camera moves forward). This follows the matrix
// construction T = P_i·inv(P_s) exactly (tested); an earlier prose account said "r > 0 moves the camera
// back", which contradicts its own formula.
glm::dmat4 official_transform(double theta_deg, double phi_deg, double r, double radius);
Trajectory official_trajectory(const OrbitAngles& per_frame, double radius, const std::string& description = "");

// ---- (b) canonical presets -----------------------------------------------------------------------------
// Every preset ramps linearly from the identity at frame 0 to `magnitude` at the last frame:
// a_i = magnitude · i / (frames − 1). The target camera pose C_i (in source-camera coordinates, OpenCV
// axes) is, with Rx, Ry as above:
//   pan_left    C = Ry(−a)            camera turns left (view direction towards −x); the scene moves right
//   pan_right   C = Ry(+a)
//   tilt_up     C = Rx(+a)            camera turns up (towards −y); the scene moves down
//   tilt_down   C = Rx(−a)
//   dolly_in    camera centre at (0, 0, +a·R)   moves forward (towards the scene)
//   dolly_out   camera centre at (0, 0, −a·R)
//   truck_left  camera centre at (−a·R, 0, 0)  moves left; the scene moves right
//   truck_right camera centre at (+a·R, 0, 0)
//   arc_left    orbit about the pivot (0,0,R) around the y axis: C = [Ry(+a) | p + Ry(+a)·(0,0,−R)],
//               p = (0,0,R): the camera moves left and turns right to keep the pivot centred
//   arc_right   the same with −a
// Units of `magnitude`: degrees for pan/tilt/arc, multiples of R (the radius, official_radius) for
// dolly/truck. T_i = C_i⁻¹.
const std::vector<std::string>& canonical_preset_names();
bool is_canonical_preset(const std::string& name);
double canonical_default_magnitude(const std::string& name);  // 15° pan/tilt, 20° arc, 0.25 R dolly/truck
Trajectory canonical_preset(const std::string& name, int frames, double magnitude, double radius);

// ---- resolving what a user typed ----------------------------------------------------------------------
// spec: an official preset name ("loop1"), a canonical preset with an optional magnitude ("pan_left",
// "arc_right:30"), or a file: *.json (trajectory_json.hpp), *.gltf / *.glb (trajectory_gltf.hpp), anything
// else is read as an official three-line file. `radius` is official_radius(...) of the clip. A file with a
// frame count other than `frames` is an error naming both counts.
Trajectory load_trajectory(const std::string& spec, int frames, double radius);

// Rigid-transform helpers (OpenCV axes).
glm::dmat4 rotation_x(double radians);
glm::dmat4 rotation_y(double radians);
glm::dmat4 translation(const glm::dvec3& t);

}  // namespace dvs::geometry
