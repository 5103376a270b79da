// `dvs run` end to end on the synthetic scene with the conformance pack's tiny model (its positional table
// fixes the size: 9 frames of 64×64), as a user runs it.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "geometry/synthetic_scene.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

struct PipelineInputs {
  test::TempDir dir;
  std::filesystem::path video = dir / "scene.mp4", depth = dir / "depth.npy", cache = dir / "cache";
  PipelineInputs() {
    geometry::SyntheticSceneSpec spec;
    spec.frames = 9;
    spec.height = 64;
    spec.width = 64;
    spec.K = geometry::Intrinsics::official_default(64, 64);
    auto clip = geometry::render_synthetic(spec);
    write_video(video, clip.rgb, 10.0);
    write_npy(depth, clip.depth);
  }
  std::string command(const std::filesystem::path& out, const std::string& extra = "") const {
    return test::program("dvs") + " run --video " + video.string() + " --depth " + depth.string() +
           " --metric-depth --model " + (test::golden_path() / "model").string() +
           " --prompt 'a red fox' --frames 9 --size 64x64 --steps 4 --inversion-steps 3 --progress json --cache-dir " +
           cache.string() + " --out " + out.string() + " " + extra;
  }
};

TEST(PipelineCli, RunWritesEveryOutputAndReusesTheInversion) {
  PipelineInputs in;
  auto out = in.dir / "out";
  auto r = test::run_command(in.command(out));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\"stage\":\"sample\""), std::string::npos) << "JSON progress events";
  for (const char* f : {"output.mp4", "render.mp4", "mask.mp4", "comparison.mp4", "run.json"})
    EXPECT_TRUE(std::filesystem::exists(out / f)) << f;
  VideoInfo info;
  HostTensor output = read_video(out / "output.mp4", {}, &info);
  EXPECT_EQ(output.shape, (Shape{9, 3, 64, 64}));
  EXPECT_NEAR(info.fps, 10.0, 1e-3);
  HostTensor cmp = read_video(out / "comparison.mp4");
  EXPECT_EQ(cmp.shape, (Shape{9, 3, 64, 192}));
  auto run = nlohmann::json::parse(std::ifstream(out / "run.json"));
  for (const char* k : {"dvs_version", "device", "driver", "inputs", "settings", "seconds", "peak_device_bytes", "outputs"})
    EXPECT_TRUE(run.contains(k)) << k;
  EXPECT_EQ(run["settings"]["seed"], 42);
  EXPECT_EQ(run["settings"]["t0"], 749);  // 4 steps at strength 0.95: 749, 499, 249
  EXPECT_FALSE(run["inversion_from_cache"].get<bool>());
  EXPECT_GT(run["peak_device_bytes"].get<double>(), 0);

  auto again = test::run_command(in.command(in.dir / "out2", "--guidance 3 --seed 7"));
  ASSERT_EQ(again.exit_code, 0) << again.output;
  auto run2 = nlohmann::json::parse(std::ifstream(in.dir / "out2" / "run.json"));
  EXPECT_TRUE(run2["inversion_from_cache"].get<bool>());
}

TEST(PipelineCli, BadInputsFailClearlyAndWriteNothing) {
  PipelineInputs in;
  auto out = in.dir / "bad";
  struct Case {
    std::string extra, expect;
  } cases[] = {
      {"--frames 8", "4k+1"},
      {"--preset fancy", "--preset"},
      {"--strength 0.001", "strength"},
      {"--guidance -1", "--guidance"},
      {"--model " + (in.dir / "no_model").string(), "no_model"},
      {"--trajectory nowhere", "nowhere"},
  };
  for (const Case& c : cases) {
    auto r = test::run_command(in.command(out, c.extra));
    EXPECT_NE(r.exit_code, 0) << c.extra;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.extra << "\n" << r.output;
    EXPECT_FALSE(std::filesystem::exists(out / "output.mp4")) << c.extra;
    EXPECT_FALSE(std::filesystem::exists(out / "run.json")) << c.extra;
  }
}

}  // namespace
}  // namespace dvs
