// run.json records every setting a run used (absolute paths, the intrinsics, tile size, --points, --trim-depth,
// the camera path's poses and their hash), and `dvs run --from run.json` repeats the run from it alone, with the
// options given next to --from overriding the recorded ones. Default intrinsics keep pixels square under crop.
#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <nlohmann/json.hpp>

#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
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
