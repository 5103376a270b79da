// Crash consistency (issue 23): `dvs run`, `dvs invert`, `dvs depth` and `dvs batch` killed with SIGKILL at
// points picked (seeded, DVS_CRASH_SEED) from the trace of an uninterrupted run: one in every stage, plus the
// points whose timing matters most (a cache entry whose data is published but not its commit marker, a commit
// half done). After each kill the same command is run again, as a user would. The rerun's files must be
// byte-identical to the uninterrupted run's (run.json without timings and cache-use flags), no committed cache
// entry may be damaged, nothing temporary may remain, and until the new results are complete the folder must
// hold the earlier ones unchanged. Every kill is printed: stage, point, outcome.
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>

#include "dvs/cache.hpp"
#include "support/crash_runs.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"
#include "support/vda_pack.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

struct KillCase {
  std::string name;              // "dvs run", for the printed lines
  std::string command;           // the same command line every time
  fs::path out_dir, cache_dir;   // emptied before every try; out_dir starts with an earlier run's files
  std::string commit_point;      // the last point before which the earlier files must be untouched
  std::vector<std::string> always;  // points tried whatever the seed
};

// The files an earlier job left in the output folder (stand-ins: their bytes are what is checked) and a file of
// the user's own.
std::map<std::string, std::string> earlier_files(const std::vector<std::string>& names) {
  std::map<std::string, std::string> files{{"notes.txt", "the user's own file\n"}};
  for (const auto& n : names) files[n] = n == "run.json" ? "{\"an earlier run's\": true}\n" : "an earlier run's " + n + "\n";
  return files;
}

// Failed checks so far, to print each kill's own outcome.
struct FailureCounter : ::testing::EmptyTestEventListener {
  int count = 0;
  void OnTestPartResult(const ::testing::TestPartResult& r) override { count += r.failed() ? 1 : 0; }
};
int failures() {
  static FailureCounter* counter = [] {
    auto* c = new FailureCounter;  // owned by GoogleTest's listener list
    ::testing::UnitTest::GetInstance()->listeners().Append(c);
    return c;
  }();
  return counter->count;
}

void reset(const KillCase& c, const std::map<std::string, std::string>& earlier) {
  fs::remove_all(c.out_dir);
  fs::remove_all(c.cache_dir);
  for (const auto& [name, bytes] : earlier) test::write_text(c.out_dir / name, bytes);
}

// Compares a folder's files with the uninterrupted run's: run.json by its stable fields, the rest byte for byte.
void expect_same_files(const std::map<std::string, std::string>& got, const std::map<std::string, std::string>& want,
                       const std::string& where) {
  EXPECT_EQ(got.size(), want.size()) << where;
  for (const auto& [name, bytes] : want) {
    const auto it = got.find(name);
    if (it == got.end()) {
      ADD_FAILURE() << where << ": " << name << " is missing";
    } else if (name == "run.json") {
      EXPECT_EQ(test::stable_record(it->second), test::stable_record(bytes)) << where << ": run.json differs";
    } else {
      EXPECT_TRUE(it->second == bytes) << where << ": " << name << " differs from the uninterrupted run's";
    }
  }
}

// Runs the case uninterrupted (the reference and the trace), then kills it at each chosen point and reruns it.
void kill_and_rerun(const KillCase& c, const fs::path& work, const std::vector<std::string>& output_names) {
  const auto earlier = earlier_files(output_names);
  reset(c, earlier);
  const fs::path ref_trace = work / "trace-reference";
  const auto ref = test::run_command(test::with_crash(c.command, ref_trace));
  ASSERT_EQ(ref.exit_code, 0) << ref.output;
  const auto want = test::visible_files(c.out_dir);
  const auto trace = test::read_trace(ref_trace);
  ASSERT_FALSE(trace.empty()) << "DVS_CRASH_TRACE wrote nothing";
  long commit_n = 0;
  for (const auto& p : trace)
    if (p.name == c.commit_point) commit_n = p.n;
  ASSERT_GT(commit_n, 0) << c.commit_point << " is not in the trace";
  const auto points = test::pick_kill_points(trace, test::crash_seed(), c.always);
  std::printf("[%s] %zu crash points in an uninterrupted run, %zu tried (seed %u)\n", c.name.c_str(), trace.size(),
              points.size(), test::crash_seed());
  for (const long n : points) {
    const test::TracePoint& p = trace[size_t(n - 1)];
    const std::string where = c.name + " killed at " + std::to_string(n) + " " + p.name;
    const int failures_before = failures();
    reset(c, earlier);
    const fs::path kill_trace = work / ("trace-" + std::to_string(n));
    const auto killed = test::run_command(test::with_crash(c.command, kill_trace, n));
    const auto reached = test::read_trace(kill_trace);
    EXPECT_NE(killed.exit_code, 0) << where << "\n" << killed.output;
    ASSERT_FALSE(reached.empty()) << where;
    EXPECT_EQ(reached.back().name, p.name) << where << ": the run took another path than the uninterrupted one";
    const auto after_kill = test::visible_files(c.out_dir);
    if (n <= commit_n) {
      EXPECT_EQ(after_kill, earlier) << where << ": the earlier results were touched before the commit";
    }
    if (n > commit_n && trace.front().name == "out-locked") {
      // Killed while moving its files into place: the next job in the folder completes the move as soon as it
      // holds the folder's lock (here it is killed right there, at its first point), before any work of its own.
      const auto recovered = test::run_command(test::with_crash(c.command, work / "trace-recovery", 1));
      EXPECT_NE(recovered.exit_code, 0) << where;
      expect_same_files(test::visible_files(c.out_dir), want, where + ", its move completed by the next job");
    }
    const auto damaged = test::damaged_entries(c.cache_dir);
    EXPECT_TRUE(damaged.empty()) << where << ": a committed cache entry is damaged: " << damaged.front();

    const auto rerun = test::run_command(c.command);
    EXPECT_EQ(rerun.exit_code, 0) << where << "\n" << rerun.output;
    expect_same_files(test::visible_files(c.out_dir), want, where);
    const auto left = test::leftovers(c.out_dir), left_in_cache = test::leftovers(cache_folder(c.cache_dir));
    EXPECT_TRUE(left.empty()) << where << ": left " << left.front();
    EXPECT_TRUE(left_in_cache.empty()) << where << ": left in the cache " << left_in_cache.front();
    const bool warned = rerun.output.find("warning: ignoring the cached") != std::string::npos ||
                        rerun.output.find("warning: the cached depth") != std::string::npos;
    std::printf("  stage %-10s point %3ld %-34s -> %s%s\n", p.stage.c_str(), n, p.name.c_str(),
                failures() > failures_before ? "FAILED" : "rerun identical, nothing left over",
                warned ? " (a torn entry was reported and recomputed)" : "");
  }
}

TEST(CrashRecovery, RunKilledAnywhereIsRecoveredByTheSameCommand) {
  test::PipelineInputs in;
  KillCase c;
  c.name = "dvs run";
  c.out_dir = in.dir / "out";
  c.cache_dir = in.cache;
  c.command = test::without_progress(in.command(c.out_dir));
  c.commit_point = "publish-journal-before";
  c.always = {"cache-publish-data:eps_inv", "cache-publish-data:latent", "publish-after:mask.mp4"};
  kill_and_rerun(c, in.dir.path, {"output.mp4", "render.mp4", "mask.mp4", "comparison.mp4", "run.json"});
}

TEST(CrashRecovery, InvertKilledAnywhereIsRecoveredByTheSameCommand) {
  test::PipelineInputs in;
  KillCase c;
  c.name = "dvs invert";
  c.out_dir = in.dir / "out";
  c.cache_dir = in.cache;
  c.command = test::program("dvs") + " invert" + in.inputs() + " --quiet --out " + c.out_dir.string();
  c.commit_point = "publish-journal-before";
  c.always = {"cache-publish-data:eps_inv", "cache-publish-before:eps_inv"};
  kill_and_rerun(c, in.dir.path, {"eps_inv.npy"});
}

TEST(CrashRecovery, DepthKilledAnywhereIsRecoveredByTheSameCommand) {
  test::PipelineInputs in;
  KillCase c;
  c.name = "dvs depth";
  c.out_dir = in.dir / "out";
  c.cache_dir = in.cache;
  c.command = test::program("dvs") + " depth --quiet --video " + in.video.string() + " --depth-model " +
              test::vda_checkpoint_path().string() + " --input-size 28 --frames 9 --cache-dir " + in.cache.string() +
              " --out " + (c.out_dir / "depth.npy").string();  // .npy: a .npz holds the time it was written
  c.commit_point = "publish-before:depth.npy";
  c.always = {"cache-publish-data:depth", "publish-before:depth.npy"};
  kill_and_rerun(c, in.dir.path, {"depth.npy"});
}

// A batch killed in its second job resumes there: the first job, finished before the kill, is not run again
// (the rerun's trace shows one render stage per job it ran), and every job's files equal an uninterrupted batch's.
TEST(CrashRecovery, BatchKilledInAJobResumesThere) {
  test::PipelineInputs in;
  const fs::path jobs = in.dir / "jobs.jsonl";
  {
    std::ofstream f(jobs);
    for (int i = 0; i < 3; ++i)
      f << nlohmann::json{{"prompt", "job " + std::to_string(i)}, {"seed", i}, {"out", (in.dir / "outs" / ("job" + std::to_string(i))).string()}}.dump()
        << "\n";
  }
  const std::string command = test::program("dvs") + " batch " + jobs.string() + in.inputs() + " --quiet";
  auto reset = [&] {
    fs::remove_all(in.dir / "outs");
    fs::remove_all(in.cache);
  };
  reset();
  const fs::path ref_trace = in.dir / "trace-reference";
  const auto ref = test::run_command(test::with_crash(command, ref_trace));
  ASSERT_EQ(ref.exit_code, 0) << ref.output;
  std::vector<std::map<std::string, std::string>> want;
  for (int i = 0; i < 3; ++i) want.push_back(test::visible_files(in.dir / "outs" / ("job" + std::to_string(i))));
  const auto trace = test::read_trace(ref_trace);
  // The jobs' boundaries: each job's run starts by locking its out folder.
  std::vector<long> job_start;
  for (const auto& p : trace)
    if (p.name == "out-locked") job_start.push_back(p.n);
  ASSERT_EQ(job_start.size(), 3u);
  // Job 1: a step of its sampling, and its commit half done; job 2: its first stage.
  std::vector<long> points;
  for (const auto& p : trace)
    if (p.n > job_start[1] && p.n < job_start[2] && (p.name == "step:sample:2" || p.name == "publish-after:mask.mp4"))
      points.push_back(p.n);
  points.push_back(job_start[2] + 1);
  std::printf("[dvs batch] %zu crash points in an uninterrupted batch of 3 jobs, %zu tried\n", trace.size(), points.size());
  for (const long n : points) {
    const std::string where = "dvs batch killed at " + std::to_string(n) + " " + trace[size_t(n - 1)].name;
    const int failures_before = failures();
    reset();
    const fs::path kill_trace = in.dir / ("trace-" + std::to_string(n)), rerun_trace = in.dir / ("trace-rerun-" + std::to_string(n));
    const auto killed = test::run_command(test::with_crash(command, kill_trace, n));
    EXPECT_NE(killed.exit_code, 0) << where;
    int finished_before_kill = 0;
    for (const auto& p : test::read_trace(kill_trace)) finished_before_kill += p.name == "publish-done";
    const auto rerun = test::run_command(test::with_crash(command, rerun_trace));
    EXPECT_EQ(rerun.exit_code, 0) << where << "\n" << rerun.output;
    int jobs_run = 0;
    for (const auto& p : test::read_trace(rerun_trace)) jobs_run += p.name == "stage-begin:render";
    EXPECT_EQ(jobs_run, 3 - finished_before_kill) << where << ": the jobs finished before the kill ran again\n" << rerun.output;
    for (int i = 0; i < 3; ++i) {
      const fs::path out = in.dir / "outs" / ("job" + std::to_string(i));
      expect_same_files(test::visible_files(out), want[size_t(i)], where + ", job " + std::to_string(i));
      EXPECT_TRUE(test::leftovers(out).empty()) << where << ": left " << test::leftovers(out).front();
    }
    std::printf("  job %d point %3ld %-30s -> %d job(s) finished before the kill, %d rerun: %s\n",
                n < job_start[2] ? 1 : 2, n, trace[size_t(n - 1)].name.c_str(), finished_before_kill, jobs_run,
                failures() > failures_before ? "FAILED" : "identical");
  }
}

}  // namespace
}  // namespace dvs
