// Cameras and trajectories: the OpenCV convention, the official pose construction and tables, the canonical
// presets' directions, interpolation, JSON and glTF round trips, and clear errors on bad files.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "support/expect_error.hpp"
#include "support/source_dir.hpp"
#include "dvs/error.hpp"
#include "geometry/camera.hpp"
#include "geometry/trajectory.hpp"
#include "geometry/trajectory_gltf.hpp"
#include "geometry/trajectory_json.hpp"

// Declarations only (the implementation lives in trajectory_gltf.cpp), configured the same way.
#define TINYGLTF_NO_STB_IMAGE
#define TINYGLTF_NO_STB_IMAGE_WRITE
#define TINYGLTF_NO_EXTERNAL_IMAGE
#include <tiny_gltf.h>

namespace dvs::geometry {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir() {
  fs::path d = fs::temp_directory_path() / ("dvs_geometry_test_" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

void write_text(const fs::path& p, const std::string& s) {
  std::ofstream f(p, std::ios::binary);
  f << s;
}

double max_diff(const glm::dmat4& a, const glm::dmat4& b) {
  double d = 0;
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r) d = std::max(d, std::abs(a[c][r] - b[c][r]));
  return d;
}

using dvs::test::expect_error;

glm::dvec2 project_point(const Trajectory& t, int frame, const Intrinsics& K, glm::dvec3 X) {
  glm::dvec4 Y = t.transforms[size_t(frame)] * glm::dvec4(X, 1.0);
  glm::dvec3 p = K.project(glm::dvec3(Y));
  return {p.x, p.y};
}

TEST(GeometryCamera, OfficialDefaultAndConvention) {
  Intrinsics k = Intrinsics::official_default(1024, 576);
  EXPECT_EQ(k.fx, 500);
  EXPECT_EQ(k.fy, 500);
  EXPECT_EQ(k.cx, 512);
  EXPECT_EQ(k.cy, 288);
  Intrinsics s = Intrinsics::official_default(720, 480);
  EXPECT_NEAR(s.fx, 500.0 * 720 / 1024, 1e-12);
  EXPECT_NEAR(s.fy, 500.0 * 480 / 576, 1e-12);
  EXPECT_NEAR(s.cx, 360, 1e-12);
  EXPECT_NEAR(s.cy, 240, 1e-12);
  // Integer pixel coordinates, no +0.5: pixel (512, 288) is on the optical axis.
  glm::dvec3 X = k.unproject(512, 288, 3.0);
  EXPECT_EQ(X, glm::dvec3(0, 0, 3));
  // x right, y down, z forward.
  EXPECT_GT(k.unproject(600, 288, 2).x, 0);
  EXPECT_GT(k.unproject(512, 400, 2).y, 0);
  glm::dvec3 p = k.project(k.unproject(100, 50, 7.5));
  EXPECT_NEAR(p.x, 100, 1e-9);
  EXPECT_NEAR(p.y, 50, 1e-9);
  EXPECT_NEAR(p.z, 7.5, 1e-12);
  glm::dmat3 I = k.K() * k.K_inv();
  for (int c = 0; c < 3; ++c)
    for (int r = 0; r < 3; ++r) EXPECT_NEAR(I[c][r], c == r ? 1 : 0, 1e-12);
  Intrinsics bad = k;
  bad.fx = 0;
  EXPECT_THROW(bad.validate(), Error);
  EXPECT_THROW(k.scaled_to(0, 10), Error);
}

// T_i = P_i · inv(P_s) with P built exactly as sphere2pose/get_poses do (docs/design.md §6.2).
TEST(GeometryTrajectory, OfficialClosedFormEqualsMatrixConstruction) {
  auto pose = [](double th, double ph, double r, double R) {
    glm::dmat4 C0(1.0);
    C0[0][0] = -1;
    C0[2][2] = -1;
    C0[3][2] -= r * R;  // C0[2,3] (row 2, column 3)
    glm::dmat4 P = rotation_y(ph * M_PI / 180) * rotation_x(th * M_PI / 180) * C0;
    P[3][2] += R;
    return P;
  };
  for (auto [th, ph, r] : {std::tuple{0.0, 0.0, 0.0}, {14.179, -12.266, 0.0937}, {-9.827, 30.0, -0.16}}) {
    double R = 3.7;
    double thf = double(float(th)), phf = double(float(ph)), rf = double(float(r));
    glm::dmat4 T = pose(thf, phf, rf, R) * glm::inverse(pose(0, 0, 0, R));
    EXPECT_LT(max_diff(T, official_transform(th, ph, r, R)), 1e-12) << th << " " << ph << " " << r;
  }
  EXPECT_LT(max_diff(official_transform(0, 0, 0, 2.0), glm::dmat4(1.0)), 1e-15);
  // With no rotation a point's depth becomes z − r·R (the matrix construction above agrees).
  EXPECT_NEAR((official_transform(0, 0, 0.5, 2.0) * glm::dvec4(0, 0, 3, 1)).z, 2.0, 1e-12);
  EXPECT_EQ(official_radius(3.0), 3.0);
  EXPECT_EQ(official_radius(9.0), 5.0);
  EXPECT_THROW(official_radius(std::nan("")), Error);
}

// The embedded tables equal tests/data/official-code-trajectories.tsv (a copy of the reference file).
TEST(GeometryTrajectory, OfficialPresetsMatchTsv) {
  std::ifstream f(test::source_dir() / "tests/data/official-code-trajectories.tsv");
  ASSERT_TRUE(f) << "missing tests/data/official-code-trajectories.tsv";
  std::map<std::string, OrbitAngles> tsv;
  std::string line;
  while (std::getline(f, line)) {
    if (line.empty() || line[0] == '#' || line.rfind("traj\t", 0) == 0) continue;
    std::istringstream in(line);
    std::string name;
    int frame;
    double th, ph, r;
    ASSERT_TRUE(in >> name >> frame >> th >> ph >> r) << line;
    auto& a = tsv[name];
    ASSERT_EQ(int(a.theta_deg.size()), frame);
    a.theta_deg.push_back(th);
    a.phi_deg.push_back(ph);
    a.r.push_back(r);
  }
  ASSERT_EQ(tsv.size(), 6u);
  for (const auto& [name, want] : tsv) {
    ASSERT_TRUE(is_official_preset(name)) << name;
    OrbitAngles got = official_preset_angles(name, 49);
    ASSERT_EQ(got.theta_deg.size(), 49u);
    const double R = 2.5;
    Trajectory tr = official_trajectory(got, R);
    for (size_t i = 0; i < 49; ++i) {
      EXPECT_NEAR(got.theta_deg[i], want.theta_deg[i], 1e-5) << name << " " << i;
      EXPECT_NEAR(got.phi_deg[i], want.phi_deg[i], 1e-5) << name << " " << i;
      EXPECT_NEAR(got.r[i], want.r[i], 1e-5) << name << " " << i;
      EXPECT_LT(max_diff(tr.transforms[i], official_transform(want.theta_deg[i], want.phi_deg[i], want.r[i], R)), 1e-5);
    }
  }
  // Another frame count resamples the table; its ends stay the table's ends.
  OrbitAngles a25 = official_preset_angles("loop1", 25);
  EXPECT_EQ(a25.theta_deg.size(), 25u);
  EXPECT_NEAR(a25.theta_deg[12], tsv["loop1"].theta_deg[24], 1e-12);
  Trajectory viaspec = load_trajectory("loop2", 49, 1.5);
  EXPECT_LT(max_diff(viaspec.transforms[30], official_transform(tsv["loop2"].theta_deg[30], tsv["loop2"].phi_deg[30],
                                                                   tsv["loop2"].r[30], 1.5)), 1e-9);
}

TEST(GeometryTrajectory, OfficialFileParsingAndInterpolation) {
  // wave1's θ line is "0 30": linear, exactly like the official interp1d table.
  OrbitAngles k = parse_official_trajectory("0 30\n0 -1 -2 -1 0 3 0 -3 0 1 2\n0 0", "wave1.txt");
  OrbitAngles a = interpolate_official(k, 49);
  OrbitAngles table = official_preset_angles("wave1", 49);
  for (size_t i = 0; i < 49; ++i) {
    EXPECT_NEAR(a.theta_deg[i], table.theta_deg[i], 1e-5);
    EXPECT_EQ(a.r[i], 0.0);
  }
  // > 3 knots: a natural cubic spline through the knots (13 knots over 49 frames: every 4th frame is a knot).
  OrbitAngles l1 = interpolate_official(parse_official_trajectory(
      "0 2 10 15 12 6 0 -2 -5 -12 -8 -3 0\n0 -3 -10 -20 -30 -25 -17 -10 0\n0 0.02 0.09 0.16 0.25 0.2 0.09 0", "l1"), 49);
  const double knots[] = {0, 2, 10, 15, 12, 6, 0, -2, -5, -12, -8, -3, 0};
  for (int k2 = 0; k2 < 13; ++k2) EXPECT_NEAR(l1.theta_deg[size_t(4 * k2)], knots[k2], 1e-9);
  EXPECT_NEAR(l1.phi_deg.back(), 0, 1e-12);
  // The smoothing spline of the official code differs, but not wildly.
  OrbitAngles off = official_preset_angles("loop1", 49);
  for (size_t i = 0; i < 49; ++i) EXPECT_NEAR(l1.theta_deg[i], off.theta_deg[i], 3.0);
  // Single frame and single-knot lists.
  EXPECT_EQ(interpolate_official(parse_official_trajectory("5\n6\n0.1", "x"), 3).theta_deg, (std::vector<double>{5, 5, 5}));
  // Errors name the file and line.
  expect_error([] { parse_official_trajectory("0 1\n0 x\n0 0", "bad.txt"); }, {"bad.txt:2", "'x'"});
  expect_error([] { parse_official_trajectory("0 1\n0 1", "two.txt"); }, {"two.txt", "three lines"});
  expect_error([] { parse_official_trajectory("0\n0\n0\n0", "four.txt"); }, {"four.txt:4"});
  expect_error([] { parse_official_trajectory("0 nan\n0\n0", "nan.txt"); }, {"nan.txt:1"});
  fs::path d = temp_dir();
  write_text(d / "traj.txt", "0 10\n0 -5\n0 0.1");
  Trajectory t = load_trajectory((d / "traj.txt").string(), 5, 2.0);
  EXPECT_EQ(t.frames(), 5);
  EXPECT_LT(max_diff(t.transforms[4], official_transform(10, -5, 0.1, 2.0)), 1e-9);
  expect_error([] { load_trajectory("no_such_preset_or_file", 5, 1.0); }, {"no_such_preset_or_file", "loop1", "pan_left"});
  fs::remove_all(d);
}

// Directions of the canonical presets, in OpenCV image terms.
TEST(GeometryTrajectory, CanonicalPresetsMoveTheImageAsNamed) {
  const Intrinsics K = Intrinsics::official_default(1024, 576);
  const glm::dvec3 ahead(0, 0, 4.0);  // the pivot when R = 4
  const double R = 4.0;
  auto last = [&](const std::string& name) {
    Trajectory t = canonical_preset(name, 9, canonical_default_magnitude(name), R);
    EXPECT_LT(max_diff(t.transforms[0], glm::dmat4(1.0)), 1e-15) << name << ": frame 0 is the source view";
    return project_point(t, 8, K, ahead);
  };
  EXPECT_GT(last("pan_left").x, 512 + 10);   // camera turns left: scene moves right
  EXPECT_LT(last("pan_right").x, 512 - 10);
  EXPECT_GT(last("tilt_up").y, 288 + 10);    // camera turns up: scene moves down
  EXPECT_LT(last("tilt_down").y, 288 - 10);
  EXPECT_GT(last("truck_left").x, 512 + 10);
  EXPECT_LT(last("truck_right").x, 512 - 10);
  // dolly: the depth of the pivot changes by magnitude·R.
  Trajectory in = canonical_preset("dolly_in", 5, 0.25, R), out = canonical_preset("dolly_out", 5, 0.25, R);
  EXPECT_NEAR((in.transforms[4] * glm::dvec4(ahead, 1)).z, 3.0, 1e-12);
  EXPECT_NEAR((out.transforms[4] * glm::dvec4(ahead, 1)).z, 5.0, 1e-12);
  EXPECT_NEAR((in.transforms[2] * glm::dvec4(ahead, 1)).z, 3.5, 1e-12);  // linear ramp
  // arc: the pivot stays centred, the camera centre moves left (arc_left) / right at distance R.
  for (const char* name : {"arc_left", "arc_right"}) {
    Trajectory t = canonical_preset(name, 5, 30, R);
    glm::dvec2 p = project_point(t, 4, K, ahead);
    EXPECT_NEAR(p.x, 512, 1e-9);
    EXPECT_NEAR(p.y, 288, 1e-9);
    glm::dmat4 C = glm::inverse(t.transforms[4]);
    glm::dvec3 centre(C[3]);
    EXPECT_NEAR(glm::length(centre - ahead), R, 1e-9);
    if (std::string(name) == "arc_left") EXPECT_LT(centre.x, -1.0);
    else EXPECT_GT(centre.x, 1.0);
  }
  // pan magnitude is degrees: 15° pan moves the centre by f·tan(15°).
  EXPECT_NEAR(last("pan_left").x - 512, 500 * std::tan(15 * M_PI / 180), 1e-9);
  Trajectory spec = load_trajectory("pan_right:30", 3, R);
  EXPECT_NEAR(project_point(spec, 2, K, ahead).x - 512, -500 * std::tan(30 * M_PI / 180), 1e-9);
  expect_error([&] { load_trajectory("pan_left:abc", 3, R); }, {"pan_left:abc", "magnitude"});
  EXPECT_THROW(canonical_preset("spin", 3, 1, R), Error);
  EXPECT_EQ(canonical_preset_names().size(), 10u);
}

TEST(GeometryTrajectory, JsonRoundTripAndConventions) {
  fs::path d = temp_dir();
  Trajectory arc = canonical_preset("arc_left", 7, 25, 3.0);
  write_trajectory_json(d / "poses.json", arc);
  EXPECT_FALSE(fs::exists(d / "poses.json.tmp"));
  Trajectory back = read_trajectory_json(d / "poses.json");
  ASSERT_EQ(back.frames(), 7);
  for (int i = 0; i < 7; ++i) EXPECT_LT(max_diff(back.transforms[size_t(i)], arc.transforms[size_t(i)]), 1e-12);

  // camera_to_world, (R, t) and 16-number forms; relative_to_first; opengl axes.
  glm::dmat4 C = translation({0.5, 0, 0});  // camera moved right
  std::string c2w = R"({"convention": "camera_to_world", "poses": [
      [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1],
      {"R": [[1,0,0],[0,1,0],[0,0,1]], "t": [0.5, 0, 0]} ]})";
  Trajectory t = parse_trajectory_json(c2w, "c2w.json");
  EXPECT_LT(max_diff(t.transforms[1], glm::inverse(C)), 1e-15);
  std::string rel = R"({"convention": "world_to_camera", "relative_to_first": true, "poses": [
      [[1,0,0,2],[0,1,0,0],[0,0,1,0],[0,0,0,1]], [[1,0,0,1.5],[0,1,0,0],[0,0,1,0],[0,0,0,1]] ]})";
  Trajectory r = parse_trajectory_json(rel, "rel.json");
  EXPECT_LT(max_diff(r.transforms[0], glm::dmat4(1.0)), 1e-15);
  EXPECT_LT(max_diff(r.transforms[1], translation({-0.5, 0, 0})), 1e-15);
  // OpenGL camera moved up (+y in GL) = moved up in OpenCV (−y): the world point goes down in the image.
  std::string gl = R"({"convention": "camera_to_world", "axes": "opengl", "poses": [
      [[1,0,0,0],[0,1,0,0.5],[0,0,1,0],[0,0,0,1]] ]})";
  Trajectory g = parse_trajectory_json(gl, "gl.json");
  EXPECT_NEAR(g.transforms[0][3][1], 0.5, 1e-15);  // camera at y = −0.5 (OpenCV) sees points 0.5 lower

  expect_error([] { parse_trajectory_json(R"({"poses": []})", "a.json"); }, {"a.json", "convention"});
  expect_error([] { parse_trajectory_json(R"({"convention": "world_to_camera", "poses": []})", "b.json"); }, {"b.json", "empty"});
  expect_error([] { parse_trajectory_json(R"({"convention": "world_to_camera", "poses": [[1,2,3]]})", "c.json"); },
               {"c.json", "poses[0]"});
  expect_error([] { parse_trajectory_json(R"({"convention": "world_to_camera", "poses": [[2,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]]})", "d.json"); },
               {"d.json", "poses[0]", "rigid"});
  expect_error([] { parse_trajectory_json("{\n\"convention\": \"world_to_camera\",\n \"poses\": [ [1,0 }", "e.json"); },
               {"e.json", "line 3"});
  expect_error([] { parse_trajectory_json(R"({"convention": "sideways", "poses": [[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]]})", "f.json"); },
               {"f.json", "sideways"});
  write_text(d / "five.json", trajectory_to_json(canonical_preset("pan_left", 5, 10, 1)));
  expect_error([&] { load_trajectory((d / "five.json").string(), 4, 1.0); }, {"five.json", "5 poses", "4 frames"});
  fs::remove_all(d);
}

TEST(GeometryTrajectory, GltfRoundTripAndErrors) {
  fs::path d = temp_dir();
  Trajectory tr = canonical_preset("arc_right", 9, 35, 2.0);
  Trajectory tilt = canonical_preset("tilt_up", 9, 10, 2.0);
  for (int i = 0; i < 9; ++i) tr.transforms[size_t(i)] = tilt.transforms[size_t(i)] * tr.transforms[size_t(i)];
  PointCloud pc;
  pc.positions = {{0, 0, 2}, {0.5f, -0.2f, 3}, {-1, 0.3f, 4}};
  pc.colors = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  Intrinsics K = Intrinsics::official_default(64, 36);
  GlbExportOptions eo;
  eo.intrinsics = &K;
  write_trajectory_glb(d / "path.glb", tr, &pc, eo);
  ASSERT_TRUE(fs::exists(d / "path.glb"));
  EXPECT_FALSE(fs::exists(d / "path.glb.tmp"));
  GltfCameraOptions o;
  o.frames = 9;
  Trajectory back = read_gltf_trajectory(d / "path.glb", o);
  ASSERT_EQ(back.frames(), 9);
  for (int i = 0; i < 9; ++i) EXPECT_LT(max_diff(back.transforms[size_t(i)], tr.transforms[size_t(i)]), 1e-5) << i;
  // Sampling between keyframes interpolates: 17 frames put every other one on a keyframe.
  o.frames = 17;
  Trajectory fine = read_gltf_trajectory(d / "path.glb", o);
  for (int i = 0; i < 9; ++i) EXPECT_LT(max_diff(fine.transforms[size_t(2 * i)], tr.transforms[size_t(i)]), 1e-5);
  Trajectory via = load_trajectory((d / "path.glb").string(), 9, 1.0);
  EXPECT_LT(max_diff(via.transforms[8], tr.transforms[8]), 1e-5);
  // Translation scale.
  o.frames = 9;
  o.translation_scale = 2;
  Trajectory scaled = read_gltf_trajectory(d / "path.glb", o);
  EXPECT_NEAR(scaled.transforms[8][3][0], 2 * tr.transforms[8][3][0], 1e-5);

  // The point cloud is in the file, upright for viewers: (x, −y, −z) of the OpenCV source-camera points.
  {
    tinygltf::Model m;
    tinygltf::TinyGLTF loader;
    std::string err, warn;
    ASSERT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, (d / "path.glb").string())) << err;
    ASSERT_FALSE(m.nodes.empty());
    EXPECT_EQ(m.nodes[0].name, "point_cloud");
    const auto& prim = m.meshes[size_t(m.nodes[0].mesh)].primitives[0];
    EXPECT_EQ(prim.mode, TINYGLTF_MODE_POINTS);
    const auto& acc = m.accessors[size_t(prim.attributes.at("POSITION"))];
    ASSERT_EQ(acc.count, 3u);
    const auto& bv = m.bufferViews[size_t(acc.bufferView)];
    const float* p = reinterpret_cast<const float*>(m.buffers[size_t(bv.buffer)].data.data() + bv.byteOffset + acc.byteOffset);
    EXPECT_EQ(p[3], 0.5f);
    EXPECT_EQ(p[4], 0.2f);
    EXPECT_EQ(p[5], -3.f);
    EXPECT_EQ(m.animations.size(), 1u);
  }
  // point_cloud_from_rgbd lifts with X = z·K⁻¹(x, y, 1) and maps [−1, 1] colours to [0, 1].
  {
    const int H = 4, W = 6;
    std::vector<float> rgb(3 * H * W, 0.5f), z(H * W, 2.f);
    z[5] = 0.f;  // skipped
    Intrinsics k = Intrinsics::official_default(W, H);
    PointCloud c = point_cloud_from_rgbd(rgb.data(), z.data(), H, W, k, 1);
    ASSERT_EQ(c.positions.size(), size_t(H * W - 1));
    glm::dvec3 want = k.unproject(0, 0, 2.0);
    EXPECT_NEAR(c.positions[0].x, want.x, 1e-6);
    EXPECT_NEAR(c.positions[0].y, want.y, 1e-6);
    EXPECT_FLOAT_EQ(c.colors[0].x, 0.75f);
    EXPECT_EQ(point_cloud_from_rgbd(rgb.data(), z.data(), H, W, k, 2).positions.size(), 6u);  // rows 0, 2 × columns 0, 2, 4
  }

  // Errors.
  expect_error([&] { read_gltf_trajectory(d / "missing.glb", o); }, {"missing.glb"});
  {
    std::ifstream f(d / "path.glb", std::ios::binary);
    std::vector<char> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    std::ofstream t(d / "truncated.glb", std::ios::binary);
    t.write(bytes.data(), std::streamsize(bytes.size() / 2));
  }
  expect_error([&] { read_gltf_trajectory(d / "truncated.glb", o); }, {"truncated.glb"});
  write_text(d / "garbage.gltf", "{ not json");
  expect_error([&] { read_gltf_trajectory(d / "garbage.gltf", o); }, {"garbage.gltf"});
  write_text(d / "empty.gltf", R"({"asset": {"version": "2.0"}, "nodes": [{"name": "a"}]})");
  expect_error([&] { read_gltf_trajectory(d / "empty.gltf", o); }, {"empty.gltf", "camera"});
  GltfCameraOptions named = o;
  named.node = "nope";
  expect_error([&] { read_gltf_trajectory(d / "path.glb", named); }, {"path.glb", "nope"});
  fs::remove_all(d);
}

// A hand-written glTF like a DCC tool exports: the camera is the child of a rotated, translated rig and
// moves along its own −Z (forward) with STEP or LINEAR keyframes at t = 0, 1, 2.
std::string rig_gltf(const std::string& interpolation) {
  return R"({"asset": {"version": "2.0"},
    "buffers": [{"byteLength": 48, "uri": "data:application/octet-stream;base64,AAAAAAAAgD8AAABAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAIC/AAAAAAAAAAAAAADA"}],
    "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 12}, {"buffer": 0, "byteOffset": 12, "byteLength": 36}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "SCALAR", "min": [0], "max": [2]},
                  {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"}],
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}],
    "nodes": [{"name": "rig", "children": [1], "translation": [3, 1, 2], "rotation": [0, 0.7071068, 0, 0.7071068]},
              {"name": "cam", "camera": 0}],
    "scenes": [{"nodes": [0]}],
    "animations": [{"samplers": [{"input": 0, "output": 1, "interpolation": ")" + interpolation + R"("}],
                    "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}]}]})";
}

TEST(GeometryTrajectory, GltfStepLinearAndHierarchy) {
  fs::path d = temp_dir();
  GltfCameraOptions o;
  o.frames = 5;  // t = 0, 0.5, 1, 1.5, 2
  write_text(d / "step.gltf", rig_gltf("STEP"));
  Trajectory step = read_gltf_trajectory(d / "step.gltf", o);
  const double want_step[5] = {0, 0, 1, 1, 2};
  for (int i = 0; i < 5; ++i)
    EXPECT_LT(max_diff(step.transforms[size_t(i)], translation({0, 0, -want_step[i]})), 1e-6) << i;
  write_text(d / "linear.gltf", rig_gltf("LINEAR"));
  Trajectory lin = read_gltf_trajectory(d / "linear.gltf", o);
  for (int i = 0; i < 5; ++i) EXPECT_LT(max_diff(lin.transforms[size_t(i)], translation({0, 0, -0.5 * i})), 1e-6) << i;
  // fps sampling: frame i at i / fps seconds; past the last key the pose holds.
  o.fps = 1;
  Trajectory fps = read_gltf_trajectory(d / "linear.gltf", o);
  EXPECT_LT(max_diff(fps.transforms[1], translation({0, 0, -1})), 1e-6);
  EXPECT_LT(max_diff(fps.transforms[4], translation({0, 0, -2})), 1e-6);
  write_text(d / "cubic.gltf", rig_gltf("CUBICSPLINE"));
  expect_error([&] { read_gltf_trajectory(d / "cubic.gltf", o); }, {"cubic.gltf", "animations[0].channels[0]", "CUBICSPLINE"});
  fs::remove_all(d);
}

}  // namespace
}  // namespace dvs::geometry
