// run.json records every setting a run used (absolute paths, the intrinsics, tile size, --points, --trim-depth,
// the camera path's poses and their hash), and `dvs run --from run.json` repeats the run from it alone, with the
// options given next to --from overriding the recorded ones. Default intrinsics keep pixels square under crop.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>

#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/lora_adapter.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

using test::PipelineInputs;

nlohmann::json record(const std::filesystem::path& dir) { return nlohmann::json::parse(std::ifstream(dir / "run.json")); }

TEST(RunRecord, RecordsWhatWasUsedAndRepeatsFromIt) {
  PipelineInputs in;
  // Relative paths, from inside the temp folder: run.json must hold them absolute.
  std::string cmd = in.command(std::filesystem::path("out"), "--vae-tile 48x40 --points");
  for (const auto& p : {in.video, in.depth, in.cache}) cmd.replace(cmd.find(p.string()), p.string().size(), p.filename().string());
  const std::string model = std::filesystem::relative(in.model, in.dir.path).string();
  cmd.replace(cmd.find(in.model.string()), in.model.string().size(), model);
  auto r = test::run_command("cd " + in.dir.path.string() + " && " + cmd);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto a = record(in.dir / "out");
  EXPECT_EQ(a["inputs"]["video"], in.video.string());
  EXPECT_EQ(a["inputs"]["depth"], in.depth.string());
  EXPECT_EQ(a["inputs"]["out"], (in.dir / "out").string());
  const std::filesystem::path recorded_model = a["inputs"]["model"].get<std::string>();
  EXPECT_TRUE(recorded_model.is_absolute()) << recorded_model;
  EXPECT_TRUE(std::filesystem::equivalent(recorded_model, in.model)) << recorded_model;
  EXPECT_EQ(a["settings"]["cache_dir"], in.cache.string());
  // Square pixels under --resize crop: the 1024×576 default camera cropped to 64×64 and scaled by 64/576.
  const double f = 500.0 * 64.0 / 576.0;
  ASSERT_EQ(a["settings"]["intrinsics"].size(), 4u);
  EXPECT_NEAR(a["settings"]["intrinsics"][0].get<double>(), f, 1e-9);
  EXPECT_NEAR(a["settings"]["intrinsics"][1].get<double>(), f, 1e-9);
  EXPECT_NEAR(a["settings"]["intrinsics"][2].get<double>(), 32.0, 1e-9);
  EXPECT_NEAR(a["settings"]["intrinsics"][3].get<double>(), 32.0, 1e-9);
  EXPECT_EQ(a["settings"]["points"], true);
  EXPECT_EQ(a["settings"]["trim_depth"], false);
  EXPECT_EQ(a["settings"]["depth_fit"], "error");
  EXPECT_EQ(a["settings"]["vae_tile"], nlohmann::json::array({48, 40}));
  ASSERT_EQ(a["trajectory_poses"].size(), 9u);
  EXPECT_EQ(a["trajectory_poses"][0].size(), 16u);
  EXPECT_EQ(a["inputs"]["trajectory_poses_hash"].get<std::string>().size(), 16u);

  // Repeated from run.json alone (another folder), with --seed overridden.
  auto again = test::run_command(test::program("dvs") + " run --from " + (in.dir / "out" / "run.json").string() +
                                 " --seed 7 --progress none --out " + (in.dir / "again").string());
  ASSERT_EQ(again.exit_code, 0) << again.output;
  const auto b = record(in.dir / "again");
  auto sa = a["settings"], sb = b["settings"];
  EXPECT_EQ(sb["seed"], 7);
  sa.erase("seed"), sb.erase("seed");
  EXPECT_EQ(sa, sb) << "every other setting repeated";
  auto ia = a["inputs"], ib = b["inputs"];
  ia.erase("out"), ib.erase("out");
  EXPECT_EQ(ia, ib) << "the same inputs, camera path included";
  EXPECT_EQ(a["lora"], b["lora"]);
  EXPECT_EQ(a["trajectory_poses"], b["trajectory_poses"]);
  EXPECT_TRUE(b["inversion_from_cache"].get<bool>()) << "the same render (intrinsics typed out) and inversion settings";
}

// A run with every setting away from its default, replayed with `--from` and nothing else but a new --out, is
// the same run: the same settings key by key and byte-identical videos. Every setting in run.json is set here to
// a value other than its default, so dropping any one of them from the replay makes the replay's run.json
// differ; a setting added to run.json later must be added here (the test says which).
TEST(RunRecord, ReplayFromAloneReproducesANonDefaultRunByteForByte) {
  PipelineInputs in;
  std::filesystem::create_directories(in.dir / "lora");
  const auto adapter = test::write_lora_adapter(in.dir / "lora", {"transformer_blocks.0.attn1.to_q"}, 5, 1.0f);
  const std::string settings =
      " --video " + in.video.string() + " --depth " + in.depth.string() + " --metric-depth --model " + in.model.string() +
      " --frames 9 --size 64x64 --resize squash --intrinsics 50,52,31,33 --points --trim-depth --depth-fit stretch"
      " --preset official --steps 5 --strength 0.9 --inversion-steps 3 --k 4 --delta 3 --guidance 4.5"
      " --dynamic-cfg off --preservation-scale 0.5 --seed 11 --no-cache --vae-tile 48x40 --trajectory pan_left:0.3"
      " --prompt 'a red fox' --negative-prompt 'blurry' --lora " + adapter.string() + ":0.7";
  auto r = test::run_command(test::program("dvs") + " run --quiet" + settings + " --out " + (in.dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto a = record(in.dir / "out");
  // The settings this run made non-default; derived values (t0, the steps run) follow from them.
  const std::vector<std::string> set_here = {"preset", "prompt", "negative_prompt", "frames", "height", "width", "resize",
                                             "intrinsics", "points", "trim_depth", "depth_fit", "steps", "strength",
                                             "inversion_steps", "k", "delta", "guidance", "dynamic_cfg",
                                             "preservation_scale", "seed", "cache", "cache_dir", "vae_tiling", "vae_tile"};
  for (const auto& [key, value] : a["settings"].items())
    if (key != "t0" && key != "sampling_steps_run")
      EXPECT_NE(std::find(set_here.begin(), set_here.end(), key), set_here.end())
          << "run.json records the setting \"" << key << "\", which this test does not set to a non-default value";

  auto again = test::run_command(test::program("dvs") + " run --quiet --from " + (in.dir / "out" / "run.json").string() +
                                 " --out " + (in.dir / "again").string());
  ASSERT_EQ(again.exit_code, 0) << again.output;
  const auto b = record(in.dir / "again");
  for (const auto& [key, value] : a["settings"].items())
    EXPECT_EQ(b["settings"].value(key, nlohmann::json()), value) << "setting \"" << key << "\" not replayed";
  EXPECT_EQ(b["settings"].size(), a["settings"].size());
  auto ia = a["inputs"], ib = b["inputs"];
  ia.erase("out"), ib.erase("out");
  EXPECT_EQ(ia, ib) << "the same inputs, camera path included";
  EXPECT_EQ(a["lora"], b["lora"]);
  EXPECT_TRUE(a["lora"].is_object());
  EXPECT_EQ(a["trajectory_poses"], b["trajectory_poses"]);
  for (const char* video : {"output.mp4", "render.mp4", "mask.mp4", "comparison.mp4"}) {
    const std::string first = test::read_text(in.dir / "out" / video);
    ASSERT_FALSE(first.empty()) << video;
    EXPECT_TRUE(first == test::read_text(in.dir / "again" / video)) << video << " of the replay differs";
  }
}

// --from without --out would write into the recorded run's own folder, replacing the run being repeated: refused
// as a usage error that names the folder, before any work; --out with that folder replaces it on purpose.
TEST(RunRecord, ReplayWithoutOutIsRefused) {
  PipelineInputs in;
  auto r = test::run_command(in.command(in.dir / "out"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string before = test::read_text(in.dir / "out" / "run.json");
  r = test::run_command(test::program("dvs") + " run --quiet --from " + (in.dir / "out" / "run.json").string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--out"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find((in.dir / "out").string()), std::string::npos) << r.output;
  EXPECT_EQ(test::read_text(in.dir / "out" / "run.json"), before) << "the original run is untouched";
}

TEST(RunRecord, FromNeedsARunJson) {
  test::TempDir dir;
  test::write_text(dir / "x.json", "{\"a\": 1}");
  auto r = test::run_command(test::program("dvs") + " run --from " + (dir / "x.json").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("x.json: no \"inputs\" object: not a run.json dvs run wrote"), std::string::npos) << r.output;
  r = test::run_command(test::program("dvs") + " run --from " + (dir / "none.json").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("none.json: cannot read it"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace dvs
