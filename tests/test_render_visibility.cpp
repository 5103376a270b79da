// A camera path that leaves the scene: `dvs render` (and so run and invert, which render the same way) refuses a
// path whose every frame after the first shows nothing, and warns, naming the frames, when only some are empty.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "geometry/synthetic_scene.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

struct Scene {
  test::TempDir dir;
  std::string base;
  Scene() {
    geometry::SyntheticSceneSpec spec;
    spec.frames = 9;
    spec.height = 48;
    spec.width = 64;
    spec.K = geometry::Intrinsics::official_default(64, 48);
    const auto clip = geometry::render_synthetic(spec);
    write_video(dir / "scene.mp4", clip.rgb, 12.0);
    write_npy(dir / "depth.npy", clip.depth);
    base = test::program("dvs") + " render --video " + (dir / "scene.mp4").string() + " --depth " +
           (dir / "depth.npy").string() + " --metric-depth --size 48x64 --frames 9 --no-glb";
  }
};

TEST(RenderVisibility, PathThatLeavesTheSceneAtOnceIsRefused) {
  Scene s;
  const auto r = test::run_command(s.base + " --trajectory truck_left:1000 --out " + (s.dir / "gone").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("--trajectory truck_left:1000: frames 1-8 (8 of 9) show nothing of the scene"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("the camera leaves the scene at once"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(s.dir / "gone" / "render.mp4"));
}

// A pan of 180 degrees over 9 frames turns 22.5 degrees a frame; the 64-pixel-wide view (f = 31.25 px) spans about
// 91 degrees, so from frame 5 (112.5 degrees) on nothing of the scene is in view: at least frames 5-8 are empty.
TEST(RenderVisibility, SomeEmptyFramesAreAWarningNamingThem) {
  Scene s;
  const auto r = test::run_command(s.base + " --trajectory pan_left:180 --out " + (s.dir / "pan").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const HostTensor mask = read_npy(s.dir / "pan" / "mask.npy");
  const int64_t plane = mask.shape[1] * mask.shape[2];
  int empty = 0;
  for (int64_t f = 0; f < mask.shape[0]; ++f) {
    float seen = 0;
    for (int64_t i = 0; i < plane; ++i) seen += mask.as<float>()[f * plane + i];
    empty += seen == 0;
  }
  EXPECT_GE(empty, 4);
  EXPECT_LT(empty, 8);
  EXPECT_NE(r.output.find("dvs: warning: --trajectory pan_left:180: frames "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("-8 (" + std::to_string(empty) + " of 9) show nothing of the scene"), std::string::npos)
      << r.output;
  // A path that stays in view says nothing of the kind.
  const auto fine = test::run_command(s.base + " --trajectory pan_left:5 --out " + (s.dir / "ok").string());
  ASSERT_EQ(fine.exit_code, 0) << fine.output;
  EXPECT_EQ(fine.output.find("show nothing"), std::string::npos) << fine.output;
}

}  // namespace
}  // namespace dvs
