// `dvs invert`, `dvs encode-prompt`, `dvs batch` and Ctrl-C, run as a user runs them, on the synthetic scene
// with the conformance pack's tiny model.
#include <gtest/gtest.h>
#include <signal.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <thread>

#include "dvs/cache.hpp"
#include "io/npy.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

using test::PipelineInputs;

TEST(CliInvert, WritesEpsInvAndRunReusesIt) {
  PipelineInputs in;
  const auto inv_out = in.dir / "inv";
  auto inv = test::run_command(test::program("dvs") + " invert" + in.inputs() + " --quiet --out " + inv_out.string());
  ASSERT_EQ(inv.exit_code, 0) << inv.output;
  const HostTensor eps = read_npy(inv_out / "eps_inv.npy");
  EXPECT_EQ(eps.shape, (Shape{3, 4, 8, 8}));  // 9 frames -> 3 latent frames, 64/8, 4 latent channels
  std::smatch m;
  ASSERT_TRUE(std::regex_search(inv.output, m, std::regex("cached (\\S+)"))) << inv.output;
  const HostTensor cached = read_npy(m[1].str());
  EXPECT_EQ(cached.data, eps.data) << "eps_inv.npy is what the cache holds";

  auto run = test::run_command(in.command(in.dir / "out", "--guidance 2 --seed 3"));
  ASSERT_EQ(run.exit_code, 0) << run.output;
  auto record = nlohmann::json::parse(std::ifstream(in.dir / "out" / "run.json"));
  EXPECT_TRUE(record["inversion_from_cache"].get<bool>());

  // Another inversion setting is another cache entry.
  auto other = test::run_command(in.command(in.dir / "out2", "--inversion-steps 2"));
  ASSERT_EQ(other.exit_code, 0) << other.output;
  EXPECT_FALSE(nlohmann::json::parse(std::ifstream(in.dir / "out2" / "run.json"))["inversion_from_cache"].get<bool>());
}

TEST(CliInvert, TakesNoSamplingOptions) {
  PipelineInputs in;
  auto r = test::run_command(test::program("dvs") + " invert" + in.inputs() + " --guidance 3 --out " + (in.dir / "x").string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("unknown option --guidance"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(in.dir / "x" / "eps_inv.npy"));
}

TEST(CliEncodePrompt, MatchesTheT5Golden) {
  test::TempDir dir;
  const auto pack = test::golden_path();
  const auto prompts = nlohmann::json::parse(std::ifstream(pack / "tokenizer" / "prompts.json"));
  const std::string prompt = prompts.at(0).get<std::string>();  // "a red fox", the t5_text_to_embeddings case
  ASSERT_EQ(prompt.find('\''), std::string::npos);
  auto r = test::run_command(test::program("dvs") + " encode-prompt --model " + (pack / "model").string() + " --prompt '" +
                             prompt + "' --out " + (dir / "fox.npy").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const HostTensor ours = read_npy(dir / "fox.npy"), ref = read_npy(pack / "t5" / "text_embeds.npy");
  ASSERT_EQ(ours.shape, (Shape{1, 8, 32}));  // [1, max_text_seq_length, d_model]
  ASSERT_EQ(ours.shape, ref.shape);
  for (int64_t i = 0; i < ours.numel(); ++i) {
    const float a = ours.as<float>()[i], b = ref.as<float>()[i];
    ASSERT_LE(std::abs(a - b), 1e-5 + 1e-4 * std::abs(b)) << "element " << i;  // the pack's tolerance for this case
  }
  auto no_model = test::run_command(test::program("dvs") + " encode-prompt --model " + (dir / "none").string() +
                                    " --prompt x --out " + (dir / "x.npy").string());
  EXPECT_NE(no_model.exit_code, 0);
  EXPECT_NE(no_model.output.find("no such model folder"), std::string::npos) << no_model.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.npy"));
}

TEST(CliBatch, ShardsCoverEveryJobOnceFailuresAreReportedAndReRunsSkip) {
  PipelineInputs in;
  const auto jobs = in.dir / "jobs.jsonl";
  // Job 3's metric depth is negative everywhere: it passes the batch's up-front checks (they read the header:
  // frames, size) and fails in its render stage, where the values are read (a trajectory that does not exist or
  // a depth of the wrong length would stop the whole shard before any job, see BatchPreflight in
  // test_run_preflight.cpp).
  const int kJobs = 5, kBad = 3;
  write_npy(in.dir / "depth_bad.npy", HostTensor::from_f32({9, 64, 64}, std::vector<float>(9 * 64 * 64, -1.0f)));
  {
    std::ofstream f(jobs);
    f << "# video, depth and model come from the command line\n";
    for (int i = 0; i < kJobs; ++i) {
      nlohmann::json job{{"prompt", "job " + std::to_string(i)},
                         {"out", (in.dir / ("out" + std::to_string(i))).string()},
                         {"trajectory", i % 2 ? "pan_left:5" : "loop1"},
                         {"seed", i}};
      if (i == kBad) job["depth"] = (in.dir / "depth_bad.npy").string();
      f << job.dump() << "\n" << (i == 1 ? "\n" : "");  // a blank line is not a job
    }
  }
  const std::string base = test::program("dvs") + " batch " + jobs.string() + in.inputs() + " --quiet";
  std::map<int, int> runs;
  for (int shard = 0; shard < 3; ++shard) {
    auto r = test::run_command(base + " --shard " + std::to_string(shard) + "/3");
    const bool has_bad = kBad % 3 == shard;
    EXPECT_EQ(r.exit_code != 0, has_bad) << r.output;
    std::smatch m;
    for (std::string s = r.output; std::regex_search(s, m, std::regex("job (\\d+) \\(jobs.jsonl:\\d+\\): running")); s = m.suffix())
      runs[std::stoi(m[1].str())]++;
    if (has_bad) EXPECT_NE(r.output.find("job 3 (jobs.jsonl:"), std::string::npos) << r.output;
    if (has_bad) EXPECT_NE(r.output.find("depth_bad.npy"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("failed"), std::string::npos) << "summary line\n" << r.output;
  }
  for (int i = 0; i < kJobs; ++i) {
    EXPECT_EQ(runs[i], 1) << "job " << i << " ran once across the shards";
    const auto out = in.dir / ("out" + std::to_string(i));
    EXPECT_EQ(std::filesystem::exists(out / "output.mp4") && std::filesystem::exists(out / "run.json"), i != kBad) << i;
  }
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(in.dir / "out4" / "run.json"))["settings"]["seed"], 4);

  auto again = test::run_command(base);  // one shard: everything
  EXPECT_NE(again.exit_code, 0) << "job 3 still fails";
  EXPECT_EQ(test::count_of(again.output, ": running"), 1u) << "only the failed job runs again\n" << again.output;
  EXPECT_NE(again.output.find("job 3 (jobs.jsonl:6): running"), std::string::npos) << again.output;
  EXPECT_NE(again.output.find("5 jobs: 0 done, 4 skipped (already done), 1 failed"), std::string::npos) << again.output;
}

TEST(CliBatch, BadJobsFileAndShardFailClearly) {
  test::TempDir dir;
  const auto dvs = test::program("dvs");
  auto missing = test::run_command(dvs + " batch " + (dir / "none.jsonl").string());
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE(missing.output.find("none.jsonl"), std::string::npos) << missing.output;
  test::write_text(dir / "bad.jsonl", "{\"prompt\": \"x\"}\nnot json\n");
  auto bad = test::run_command(dvs + " batch " + (dir / "bad.jsonl").string());
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("bad.jsonl:2"), std::string::npos) << bad.output;
  auto shard = test::run_command(dvs + " batch " + (dir / "bad.jsonl").string() + " --shard 3/3");
  EXPECT_NE(shard.exit_code, 0);
  EXPECT_NE(shard.output.find("--shard"), std::string::npos) << shard.output;
}

// Ctrl-C while the transformer runs: exit 130, one message, nothing that looks finished, no temporary files.
TEST(CliInterrupt, SigintStopsARunCleanly) {
  PipelineInputs in;
  const auto out = in.dir / "out", log = in.dir / "log.txt";
  // Many steps, so the signal lands while steps remain (cancellation is polled before every step).
  const int pid = test::start_command(in.command(out, "--steps 400 --inversion-steps 400 --no-cache > " + log.string() + " 2>&1"));
  ASSERT_GT(pid, 0);
  bool inverting = false;
  for (int i = 0; i < 6000 && !inverting; ++i) {  // up to a minute for the first inversion step
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    inverting = test::read_text(log).find("\"stage\":\"invert\",\"step\":1,") != std::string::npos;
  }
  ASSERT_TRUE(inverting) << test::read_text(log);
  kill(pid, SIGINT);
  EXPECT_EQ(test::wait_command(pid), 130) << test::read_text(log);
  const std::string output = test::read_text(log);
  EXPECT_NE(output.find("interrupted"), std::string::npos) << output;
  EXPECT_EQ(output.find("dvs: error"), std::string::npos) << output;  // an interruption, not a failure
  EXPECT_NE(output.find("{\"event\":\"error\",\"exit_code\":130,\"message\":\"interrupted\"}"), std::string::npos) << output;
  for (const auto& name : test::files_in(out)) ADD_FAILURE() << "left in the output folder: " << name;
  for (const auto& name : test::files_in(cache_folder(in.cache))) EXPECT_EQ(name.find("partial"), std::string::npos) << name;
}

}  // namespace
}  // namespace dvs
