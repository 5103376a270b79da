// scene.glb as dvs writes it: valid glTF 2.0 (the Khronos validator, and zfar > znear, which glTF requires),
// with far points (the sky of depth-from-disparity, at 10⁴ units) left out so "fit to view" shows the scene.
#include <gtest/gtest.h>

#include <tiny_gltf.h>

#include <filesystem>

#include "geometry/synthetic_scene.hpp"
#include "geometry/trajectory.hpp"
#include "geometry/trajectory_gltf.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/files.hpp"
#include "support/gltf_validator.hpp"
#include "support/process.hpp"

namespace dvs::geometry {
namespace {

namespace fs = std::filesystem;

// A scene at depth 4..6 plus a few sky points at 10⁴, as disparity conversion produces.
PointCloud scene_with_sky() {
  PointCloud pc;
  for (int i = 0; i < 100; ++i) {
    pc.positions.push_back({0.05f * float(i % 10) - 0.25f, 0.05f * float(i / 10) - 0.25f, 4.0f + 0.02f * float(i)});
    pc.colors.push_back({0.5f, 0.5f, 0.5f});
  }
  for (int i = 0; i < 10; ++i) {
    pc.positions.push_back({float(i), -50.0f, 1e4f});
    pc.colors.push_back({0.2f, 0.4f, 1.0f});
  }
  return pc;
}

tinygltf::Model read_glb(const fs::path& p) {
  tinygltf::Model m;
  tinygltf::TinyGLTF loader;
  std::string err, warn;
  EXPECT_TRUE(loader.LoadBinaryFromFile(&m, &err, &warn, p.string())) << err;
  return m;
}

TEST(GeometryGltfExport, CameraHasAFiniteZfarBeyondTheSceneAndFarPointsAreClipped) {
  test::TempDir d;
  const Trajectory tr = canonical_preset("arc_right", 9, 30, 5.0);
  const PointCloud pc = scene_with_sky();
  const Intrinsics K = Intrinsics::official_default(64, 48);
  GlbExportOptions eo;
  eo.intrinsics = &K;
  write_trajectory_glb(d / "scene.glb", tr, &pc, eo);
  const tinygltf::Model m = read_glb(d / "scene.glb");
  ASSERT_EQ(m.cameras.size(), 1u);
  const auto& cam = m.cameras[0].perspective;
  EXPECT_GT(cam.znear, 0.0);
  EXPECT_GT(cam.zfar, cam.znear);  // glTF 2.0: zfar, when present, must exceed znear (0 is invalid)

  // The point cloud holds the 100 scene points only; its bounds (world = camera with y, z flipped) stop
  // at the scene's far side, and zfar reaches past them.
  const tinygltf::Accessor* positions = nullptr;
  for (const auto& mesh : m.meshes)
    if (mesh.name == "point_cloud") positions = &m.accessors[size_t(mesh.primitives[0].attributes.at("POSITION"))];
  ASSERT_NE(positions, nullptr);
  EXPECT_EQ(positions->count, 100u);
  ASSERT_EQ(positions->minValues.size(), 3u);
  EXPECT_NEAR(positions->minValues[2], -(4.0 + 0.02 * 99), 1e-4);  // the farthest kept point
  EXPECT_NEAR(positions->maxValues[2], -4.0, 1e-4);                 // the nearest
  EXPECT_GT(cam.zfar, 6.0);
  EXPECT_LT(cam.zfar, 100.0);  // not stretched to the sky

  // The clip keeps everything within ratio × median depth and nothing else; ratio 0 keeps all.
  EXPECT_EQ(clip_far_points(pc, 8).positions.size(), 100u);
  EXPECT_EQ(clip_far_points(pc, 0).positions.size(), 110u);
  EXPECT_EQ(clip_far_points(pc, 1.0).positions.size(), 56u);  // median = z[55] of the sorted 110 = 5.1
}

TEST(GeometryGltfExport, ExportedSceneAndDvsRenderOutputPassTheKhronosValidator) {
  DVS_REQUIRE_GLTF_VALIDATOR(validator);
  test::TempDir d;
  const Trajectory tr = canonical_preset("dolly_in", 5, 0.5, 5.0);
  const PointCloud pc = scene_with_sky();
  write_trajectory_glb(d / "direct.glb", tr, &pc);
  write_trajectory_glb(d / "path_only.glb", tr, nullptr);
  for (const char* f : {"direct.glb", "path_only.glb"}) {
    const auto r = test::validate_gltf(validator, d / f);
    EXPECT_EQ(r.exit_code, 0) << f << "\n" << r.output;
  }

  // What `dvs render` writes for a user.
  SyntheticSceneSpec spec;
  spec.frames = 5;
  spec.height = 48;
  spec.width = 64;
  spec.K = Intrinsics::official_default(64, 48);
  const auto clip = render_synthetic(spec);
  write_video(d / "scene.mp4", clip.rgb, 12.0);
  write_npy(d / "depth.npy", clip.depth);
  const auto render = test::run_command(test::program("dvs") + " render --video " + (d / "scene.mp4").string() +
                                        " --depth " + (d / "depth.npy").string() +
                                        " --metric-depth --trajectory arc_left --size 48x64 --frames 5 --out " +
                                        (d / "out").string());
  ASSERT_EQ(render.exit_code, 0) << render.output;
  const auto r = test::validate_gltf(validator, d / "out" / "scene.glb");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("0 errors, 0 warnings"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace dvs::geometry
