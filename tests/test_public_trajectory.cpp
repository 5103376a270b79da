// dvs/trajectory.hpp: key poses → per-frame path, and the path through the trajectory files dvs reads.
// Expected poses are written out from cos/sin by hand (not through the quaternion code under test).
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "dvs/error.hpp"
#include "dvs/trajectory.hpp"
#include "support/files.hpp"

namespace {

// T of a camera turned by `deg` about y (OpenCV axes, C = Ry) with its centre at c: T = [Rᵀ | −Rᵀc].
dvs::Pose camera_about_y(double deg, double cx, double cy, double cz) {
  const double a = deg * std::numbers::pi / 180, c = std::cos(a), s = std::sin(a);
  // C's rotation Ry = [[c,0,s],[0,1,0],[−s,0,c]]; its transpose:
  const double r[3][3] = {{c, 0, -s}, {0, 1, 0}, {s, 0, c}};
  dvs::Pose p;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) p.m[size_t(i * 4 + j)] = r[i][j];
    p.m[size_t(i * 4 + 3)] = -(r[i][0] * cx + r[i][1] * cy + r[i][2] * cz);
  }
  return p;
}

// A rotation about an oblique axis with a translation: no entry is a round number.
dvs::Pose oblique(double deg, double tx, double ty, double tz) {
  const double a = deg * std::numbers::pi / 180, c = std::cos(a), s = std::sin(a), k = 1 / std::sqrt(3.0);
  const double x = k, y = k, z = k, t = 1 - c;
  const double r[3][3] = {{t * x * x + c, t * x * y - s * z, t * x * z + s * y},
                          {t * x * y + s * z, t * y * y + c, t * y * z - s * x},
                          {t * x * z - s * y, t * y * z + s * x, t * z * z + c}};
  dvs::Pose p;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) p.m[size_t(i * 4 + j)] = r[i][j];
  p.m[3] = tx;
  p.m[7] = ty;
  p.m[11] = tz;
  return p;
}

void expect_near(const dvs::Pose& got, const dvs::Pose& want, double tol, const std::string& what) {
  for (size_t i = 0; i < 16; ++i) EXPECT_NEAR(got.m[i], want.m[i], tol) << what << ", element " << i;
}

std::vector<dvs::Pose> sample_path() {
  return dvs::interpolate_path({{0, dvs::Pose{}}, {5, oblique(23.7, 0.31, -0.12, 0.45)}, {11, oblique(-41.3, -0.7, 0.2, 1.1)}},
                               12);
}

}  // namespace

TEST(PublicTrajectory, KeysAreHitExactlyAndTheEndsHold) {
  const dvs::Pose a = oblique(17.3, 0.1, 0.2, -0.3), b = oblique(-33.1, 0.4, -0.5, 0.6);
  const auto path = dvs::interpolate_path({{2, a}, {6, b}}, 9);
  ASSERT_EQ(path.size(), 9u);
  for (int f : {0, 1, 2}) EXPECT_EQ(path[size_t(f)].m, a.m) << "frame " << f;
  for (int f : {6, 7, 8}) EXPECT_EQ(path[size_t(f)].m, b.m) << "frame " << f;
  EXPECT_NE(path[4].m, a.m);
  EXPECT_NE(path[4].m, b.m);
}

TEST(PublicTrajectory, MidpointOfAPureRotationIsTheHalfAngle) {
  const auto path = dvs::interpolate_path({{0, camera_about_y(0, 0, 0, 0)}, {4, camera_about_y(70, 0, 0, 0)}}, 5);
  expect_near(path[2], camera_about_y(35, 0, 0, 0), 1e-12, "frame 2 of 0°→70°");
  expect_near(path[1], camera_about_y(17.5, 0, 0, 0), 1e-12, "frame 1 of 0°→70°");
}

TEST(PublicTrajectory, CameraCentreMovesOnTheStraightLine) {
  // Turning 90° while moving from (0,0,0) to (2,0,4): half-way the camera is at (1,0,2) turned 45°.
  const auto path = dvs::interpolate_path({{0, camera_about_y(0, 0, 0, 0)}, {2, camera_about_y(90, 2, 0, 4)}}, 3);
  expect_near(path[1], camera_about_y(45, 1, 0, 2), 1e-12, "frame 1");
}

TEST(PublicTrajectory, EvenlySpacedKeyFrames) {
  EXPECT_EQ(dvs::evenly_spaced_key_frames(1, 49), (std::vector<int>{0}));
  EXPECT_EQ(dvs::evenly_spaced_key_frames(3, 49), (std::vector<int>{0, 24, 48}));
  EXPECT_EQ(dvs::evenly_spaced_key_frames(4, 10), (std::vector<int>{0, 3, 6, 9}));
  EXPECT_THROW(dvs::evenly_spaced_key_frames(5, 4), dvs::Error);
}

TEST(PublicTrajectory, BadKeysAreRefusedWithTheKeyNamed) {
  auto message = [](const std::vector<dvs::KeyPose>& keys, int frames) {
    try {
      dvs::interpolate_path(keys, frames);
    } catch (const dvs::Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message({}, 5).find("no key poses"), std::string::npos);
  EXPECT_NE(message({{7, dvs::Pose{}}}, 5).find("key pose 0 (frame 7) is outside"), std::string::npos);
  EXPECT_NE(message({{3, dvs::Pose{}}, {3, dvs::Pose{}}}, 5).find("key pose 1 (frame 3) does not come after"),
            std::string::npos);
  dvs::Pose scaled;
  scaled.m[0] = 2;
  EXPECT_NE(message({{0, scaled}}, 5).find("key pose 0 (frame 0) is not a rigid transform"), std::string::npos);
}

TEST(PublicTrajectory, JsonRoundTripGivesTheSameDoubles) {
  dvs::test::TempDir dir;
  const auto path = sample_path();
  const std::string file = (dir / "path.json").string();
  dvs::write_trajectory_json(file, path, "test path");
  const auto back = dvs::load_trajectory(file, int(path.size()));
  ASSERT_EQ(back.size(), path.size());
  for (size_t i = 0; i < path.size(); ++i) EXPECT_EQ(back[i].m, path[i].m) << "frame " << i;
}

TEST(PublicTrajectory, GlbRoundTripWithinFloatPrecision) {
  // glTF holds floats (translation, unit quaternion): 1e-6 on entries of order 1.
  dvs::test::TempDir dir;
  const auto path = sample_path();
  const std::string file = (dir / "path.glb").string();
  dvs::write_trajectory_glb(file, path);
  const auto back = dvs::load_trajectory(file, int(path.size()));
  ASSERT_EQ(back.size(), path.size());
  for (size_t i = 0; i < path.size(); ++i) expect_near(back[i], path[i], 2e-6, "frame " + std::to_string(i));
}

TEST(PublicTrajectory, GlbNeedsTheGlbExtension) {
  dvs::test::TempDir dir;
  try {
    dvs::write_trajectory_glb((dir / "path.gltf").string(), sample_path());
    FAIL() << "a .gltf name was accepted";
  } catch (const dvs::Error& e) {
    EXPECT_NE(std::string(e.what()).find("name the file *.glb"), std::string::npos) << e.what();
  }
}

TEST(PublicTrajectory, PresetsLoadAsPoses) {
  // pan_right:90 ends with the camera turned 90° about y (trajectory.hpp: C = Ry(+a)).
  const auto poses = dvs::load_trajectory("pan_right:90", 3);
  ASSERT_EQ(poses.size(), 3u);
  expect_near(poses[0], camera_about_y(0, 0, 0, 0), 1e-12, "frame 0");
  expect_near(poses[2], camera_about_y(90, 0, 0, 0), 1e-12, "frame 2");
}
