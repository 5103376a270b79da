// The command-line programs as a user runs them: exit codes and messages.
#include <gtest/gtest.h>

#include <string>

#include "support/process.hpp"

namespace {

using dvs::test::run_command;
const std::string kDvs = dvs::test::program("dvs");

TEST(Cli, InfoListsDevices) {
  auto r = run_command(kDvs + " info");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Device 0:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("maxStorageBufferRange"), std::string::npos);
  EXPECT_NE(r.output.find("maxMemoryAllocationSize"), std::string::npos);
  EXPECT_NE(r.output.find("maxComputeSharedMemorySize"), std::string::npos);
  EXPECT_NE(r.output.find("selected"), std::string::npos);
}

TEST(Cli, InfoWithUnknownDeviceFails) {
  auto r = run_command(kDvs + " info --device no-such-gpu");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("no-such-gpu"), std::string::npos) << r.output;
  auto env = run_command("DVS_DEVICE=no-such-gpu-env " + kDvs + " info");
  EXPECT_NE(env.exit_code, 0);
  EXPECT_NE(env.output.find("no-such-gpu-env"), std::string::npos) << env.output;
}

TEST(Cli, UnknownCommandAndHelp) {
  EXPECT_EQ(run_command(kDvs + " --help").exit_code, 0);
  auto r = run_command(kDvs + " frobnicate");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("unknown command"), std::string::npos);
  EXPECT_NE(run_command(kDvs + " info --bogus").exit_code, 0);
}

}  // namespace

// `dvs render` on the synthetic scene, as a user runs it.
#include <filesystem>

#include "geometry/synthetic_scene.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/files.hpp"

namespace {

struct SceneFiles {
  dvs::test::TempDir dir;
  std::filesystem::path video, depth;
  explicit SceneFiles(int frames = 5) {
    dvs::geometry::SyntheticSceneSpec spec;
    spec.frames = frames;
    spec.height = 48;
    spec.width = 64;
    spec.K = dvs::geometry::Intrinsics::official_default(64, 48);
    auto clip = dvs::geometry::render_synthetic(spec);
    video = dir / "scene.mp4";
    depth = dir / "depth.npy";
    dvs::write_video(video, clip.rgb, 12.0);
    dvs::write_npy(depth, clip.depth);
  }
};

TEST(CliRender, WritesEveryOutput) {
  SceneFiles s;
  auto out = s.dir / "out";
  auto r = dvs::test::run_command(kDvs + " render --video " + s.video.string() + " --depth " + s.depth.string() +
                                  " --metric-depth --trajectory pan_left:5 --size 48x64 --frames 5 --out " + out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* f : {"render.mp4", "mask.mp4", "mask.npy", "poses.json", "scene.glb"})
    EXPECT_TRUE(std::filesystem::exists(out / f)) << f;
  dvs::HostTensor mask = dvs::read_npy(out / "mask.npy");
  EXPECT_EQ(mask.shape, (dvs::Shape{5, 48, 64}));
  dvs::VideoInfo info;
  dvs::HostTensor render = dvs::read_video(out / "render.mp4", {}, &info);
  EXPECT_EQ(render.shape, (dvs::Shape{5, 3, 48, 64}));
  EXPECT_NEAR(info.fps, 12.0, 1e-3);  // output keeps the input fps
}

// Depth written for the whole source clip (as a video depth estimator does) follows the video's --frames cut;
// depth of another length needs --trim-depth.
TEST(CliRender, WholeClipDepthFollowsTheFrameCut) {
  SceneFiles s(9);
  const std::string base = kDvs + " render --video " + s.video.string() + " --metric-depth --size 48x64 --frames 5 ";
  auto r = dvs::test::run_command(base + "--depth " + s.depth.string() + " --out " + (s.dir / "a").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(dvs::read_npy(s.dir / "a" / "mask.npy").shape, (dvs::Shape{5, 48, 64}));
  dvs::HostTensor seven = dvs::read_npy(s.depth);
  seven.shape[0] = 7;
  seven.data.resize(size_t(seven.numel()) * 4);
  dvs::write_npy(s.dir / "depth7.npy", seven);
  r = dvs::test::run_command(base + "--depth " + (s.dir / "depth7.npy").string() + " --out " + (s.dir / "b").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("depth7.npy: holds 7 depth frames but the job uses --frames 5 (and the video holds 9): "
                          "--trim-depth uses its first 5"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("preflight found 1 problem"), std::string::npos) << r.output;
  r = dvs::test::run_command(base + "--trim-depth --depth " + (s.dir / "depth7.npy").string() + " --out " +
                             (s.dir / "c").string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
}

TEST(CliRender, BadInputsFailClearlyAndWriteNothing) {
  SceneFiles s;
  auto out = s.dir / "out";
  std::string base = kDvs + " render --video " + s.video.string() + " --size 48x64 --frames 5 --out " + out.string();
  struct Case {
    std::string args, expect;
  } cases[] = {
      {" --depth " + (s.dir / "nope.npy").string(), "nope.npy"},
      {" --depth " + s.depth.string() + " --trajectory no_such_path", "no_such_path"},
      {" --depth " + s.depth.string() + " --frames -3", "--frames"},
      {" --depth " + s.depth.string() + " --size 47x64", "multiples of 8"},
      {" --depth " + s.depth.string() + " --bogus 1", "unknown option --bogus"},
  };
  for (const Case& c : cases) {
    auto r = dvs::test::run_command(base + c.args);
    EXPECT_NE(r.exit_code, 0) << c.args;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << "\n" << r.output;
    EXPECT_FALSE(std::filesystem::exists(out / "render.mp4")) << c.args;
  }
  auto missing_video = dvs::test::run_command(kDvs + " render --video " + (s.dir / "none.mp4").string() + " --depth " +
                                              s.depth.string() + " --out " + out.string());
  EXPECT_NE(missing_video.exit_code, 0);
  EXPECT_NE(missing_video.output.find("none.mp4"), std::string::npos) << missing_video.output;
}

}  // namespace
