// Every 4k+1 frame count runs end to end (1 through 25 on the pack's tiny model, smallest settings). An even
// latent frame count (5, 13, 21 frames) used to fail only in the write stage, after the whole pipeline: the VAE
// decodes 4·Fl frames there (diffusers' batching), 3 more than the render has.
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

TEST(RunFrames, EveryFourKPlusOneFrameCountRunsEndToEnd) {
  test::TempDir dir;
  geometry::SyntheticSceneSpec spec;
  spec.frames = 25;
  spec.height = 64;
  spec.width = 64;
  spec.K = geometry::Intrinsics::official_default(64, 64);
  const auto clip = geometry::render_synthetic(spec);
  write_video(dir / "scene.mp4", clip.rgb, 10.0);
  write_npy(dir / "depth.npy", clip.depth);  // the whole clip's depth follows the --frames cut
  for (int frames = 1; frames <= 25; frames += 4) {
    const auto out = dir / ("f" + std::to_string(frames));
    // One inversion step and one sampling step: the frame count is what is tested, not the diffusion.
    auto r = test::run_command(test::program("dvs") + " run --video " + (dir / "scene.mp4").string() + " --depth " +
                               (dir / "depth.npy").string() + " --metric-depth --model " + test::golden_path().string() +
                               "/model --size 64x64 --steps 2 --strength 0.5 --inversion-steps 1 --no-cache --quiet" +
                               " --prompt 'a red fox' --frames " + std::to_string(frames) + " --out " + out.string());
    ASSERT_EQ(r.exit_code, 0) << "--frames " << frames << "\n" << r.output;
    EXPECT_EQ(read_video(out / "output.mp4").shape, (Shape{frames, 3, 64, 64})) << frames;
    EXPECT_EQ(read_video(out / "comparison.mp4").shape, (Shape{frames, 3, 64, 192})) << frames;
    EXPECT_EQ(read_video(out / "render.mp4").shape, (Shape{frames, 3, 64, 64})) << frames;
    auto record = nlohmann::json::parse(std::ifstream(out / "run.json"));
    EXPECT_EQ(record["settings"]["frames"], frames);
  }
}

}  // namespace
}  // namespace dvs
