// `dvs render --save-npy`: render.npy holds the render before the lossy video encode, value for value what the
// splat renderer gives for the decoded clip, its depth and the path (geometry::render_clip, run here in-process).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "geometry/splat.hpp"
#include "geometry/synthetic_scene.hpp"
#include "geometry/trajectory.hpp"
#include "io/depth.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/files.hpp"
#include "support/gpu.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

class CliRenderNpy : public test::GpuTest {};

// A synthetic 48×64 RGB-D clip of `frames` frames as dir/scene.mp4 and its metric depth as dir/depth.npy.
geometry::RgbdClip write_scene_clip(const std::filesystem::path& dir, int frames) {
  geometry::SyntheticSceneSpec spec;
  spec.frames = frames;
  spec.height = 48;
  spec.width = 64;
  spec.K = geometry::Intrinsics::official_default(64, 48);
  auto scene = geometry::render_synthetic(spec);
  write_video(dir / "scene.mp4", scene.rgb, 12.0);
  write_npy(dir / "depth.npy", scene.depth);
  return scene;
}

TEST_F(CliRenderNpy, RenderNpyEqualsTheSplatRenderOfTheClip) {
  test::TempDir dir;
  const auto scene = write_scene_clip(dir.path, 5);
  const auto r = test::run_command(test::program("dvs") + " render --video " + (dir / "scene.mp4").string() +
                                   " --depth " + (dir / "depth.npy").string() +
                                   " --metric-depth --size 48x64 --frames 5 --no-glb --trajectory arc_left:10 "
                                   "--save-npy --out " + (dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find((dir / "out" / "render.npy").string()), std::string::npos) << r.output;
  const HostTensor saved = read_npy(dir / "out" / "render.npy");
  ASSERT_EQ(saved.shape, (std::vector<int64_t>{5, 3, 48, 64}));

  // The same render in-process: the clip as dvs decodes it, the depth as given (metric, same size), the path.
  VideoReadOptions vo;
  vo.max_frames = 5;
  vo.height = 48;
  vo.width = 64;
  const HostTensor rgb = read_video(dir / "scene.mp4", vo);
  const auto path = geometry::load_trajectory("arc_left:10", 5, geometry::official_radius(centre_depth(scene.depth)));
  // dvs render's camera without --intrinsics: square pixels, f = 500 px at 1024×576 scaled to cover (camera.hpp).
  const auto expected =
      geometry::render_clip(ctx(), rgb, scene.depth, path, geometry::Intrinsics::dvs_default(64, 48, false));
  ASSERT_EQ(expected.render.numel(), saved.numel());
  int64_t differing = 0;
  for (int64_t i = 0; i < saved.numel(); ++i) differing += saved.as<float>()[i] != expected.render.as<float>()[i];
  EXPECT_EQ(differing, 0) << "of " << saved.numel() << " values";
  const HostTensor mask = read_npy(dir / "out" / "mask.npy");
  ASSERT_EQ(mask.numel(), expected.mask.numel());
  for (int64_t i = 0; i < mask.numel(); ++i) ASSERT_EQ(mask.as<float>()[i], expected.mask.as<float>()[i]) << i;

  // render.mp4 is the same frames through a lossy codec: close, not equal (a mean error of 0.050 of the [−1,1]
  // range at this tiny 48×64 size, where the codec's blocks are coarse).
  const HostTensor mp4 = read_video(dir / "out" / "render.mp4", vo);
  double err = 0;
  for (int64_t i = 0; i < saved.numel(); ++i) err += std::abs(mp4.as<float>()[i] - saved.as<float>()[i]);
  EXPECT_LT(err / double(saved.numel()), 0.1);
}

TEST(CliRenderNpyOff, NoRenderNpyWithoutTheOption) {
  test::TempDir dir;
  write_scene_clip(dir.path, 2);
  const auto r = test::run_command(test::program("dvs") + " render --video " + (dir / "scene.mp4").string() +
                                   " --depth " + (dir / "depth.npy").string() +
                                   " --metric-depth --size 48x64 --frames 2 --no-glb --trajectory pan_left:5 --out " +
                                   (dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "render.mp4"));
  EXPECT_FALSE(std::filesystem::exists(dir / "out" / "render.npy"));
}

}  // namespace
}  // namespace dvs
