// Many dvs processes at once (issue 23): one process at a time writes into an output folder (a second one is
// refused at once, naming the first); runs and batch shards sharing one cache folder never see a torn entry,
// leave every committed entry whole, and write what one process alone writes. The processes start together,
// with start offsets drawn from a few seeds so the interleavings differ.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <thread>

#include "dvs/cache.hpp"
#include "support/crash_runs.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

void expect_same_job(const fs::path& got_dir, const std::map<std::string, std::string>& want, const std::string& where) {
  const auto got = test::visible_files(got_dir);
  EXPECT_EQ(got.size(), want.size()) << where;
  for (const auto& [name, bytes] : want) {
    if (!got.count(name)) {
      ADD_FAILURE() << where << ": " << name << " is missing";
    } else if (name == "run.json") {
      EXPECT_EQ(test::stable_record(got.at(name)), test::stable_record(bytes)) << where << ": run.json differs";
    } else {
      EXPECT_TRUE(got.at(name) == bytes) << where << ": " << name << " differs from a run alone";
    }
  }
  EXPECT_TRUE(test::leftovers(got_dir).empty()) << where << ": left " << test::leftovers(got_dir).front();
}

// Waits (at most a minute) until `trace` names `point`; true when it does.
bool wait_for_point(const fs::path& trace, const std::string& point) {
  for (int i = 0; i < 6000; ++i) {
    for (const auto& p : test::read_trace(trace))
      if (p.name == point) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return false;
}

TEST(ConcurrentJobs, AFolderHeldByAnotherProcessIsRefusedAtOnce) {
  test::PipelineInputs in;
  const fs::path out = in.dir / "out";
  test::write_text(out / "notes.txt", "kept\n");
  // Another process's lock, as dvs writes it.
  const int fd = ::open((out / ".dvs-lock").c_str(), O_RDWR | O_CREAT, 0644);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(::flock(fd, LOCK_EX), 0);
  const std::string holder = "pid 4242 on host node7\n";
  ASSERT_EQ(::write(fd, holder.data(), holder.size()), ssize_t(holder.size()));
  for (const std::string& cmd : {in.command(out), test::program("dvs") + " invert" + in.inputs() + " --out " + out.string()}) {
    const auto t = std::chrono::steady_clock::now();
    const auto r = test::run_command(cmd);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find(out.string() + ": this output folder is in use by dvs process pid 4242 on host node7"),
              std::string::npos) << r.output;
    EXPECT_NE(r.output.find("wait for it to finish, or give another --out"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("\"stage\":\"render\""), std::string::npos) << "refused before any work\n" << r.output;
    std::printf("refused in %.1f s: %s\n", s, r.output.substr(0, r.output.find('\n')).c_str());
  }
  EXPECT_EQ(test::files_in(out).size(), 2u) << "nothing but the user's file and the other's lock";
  EXPECT_TRUE(fs::exists(out / ".dvs-lock")) << "the other process's lock file is not taken away";
  ::close(fd);
}

TEST(ConcurrentJobs, TwoRunsIntoOneFolderOneIsRefusedTheOtherFinishes) {
  test::PipelineInputs in;
  const fs::path out = in.dir / "out", trace = in.dir / "trace";
  const std::string cmd = test::without_progress(in.command(out));
  const int first = test::start_command(test::with_crash(cmd, trace) + " > " + (in.dir / "first.log").string() + " 2>&1");
  ASSERT_GT(first, 0);
  ASSERT_TRUE(wait_for_point(trace, "out-locked")) << test::read_text(in.dir / "first.log");
  const auto second = test::run_command(cmd);
  EXPECT_EQ(second.exit_code, 1) << second.output;
  EXPECT_NE(second.output.find("in use by dvs process pid " + std::to_string(first) + " on host"), std::string::npos)
      << second.output;
  EXPECT_EQ(test::wait_command(first), 0) << test::read_text(in.dir / "first.log");
  EXPECT_TRUE(fs::exists(out / "output.mp4"));
  EXPECT_TRUE(test::leftovers(out).empty()) << test::leftovers(out).front();
}

// Three runs of one job into three folders, sharing one cache folder, started together: each computes or
// reuses the inversion and latent entries, and each writes what a run alone writes.
TEST(ConcurrentJobs, RunsSharingACacheWriteWhatARunAloneWrites) {
  test::PipelineInputs in;
  const auto alone = test::run_command(test::without_progress(in.command(in.dir / "alone")));
  ASSERT_EQ(alone.exit_code, 0) << alone.output;
  const auto want = test::visible_files(in.dir / "alone");
  for (unsigned seed : {1u, 2u}) {
    const fs::path cache = in.dir / ("shared-cache-" + std::to_string(seed));
    std::mt19937 rng(seed);
    std::vector<int> pids;
    std::vector<int> offsets_ms;
    for (int i = 0; i < 3; ++i) {
      offsets_ms.push_back(std::uniform_int_distribution<int>(0, 400)(rng));
      std::this_thread::sleep_for(std::chrono::milliseconds(offsets_ms.back()));
      std::string cmd = test::without_progress(in.command(in.dir / ("s" + std::to_string(seed) + "-" + std::to_string(i))));
      cmd.replace(cmd.find(in.cache.string()), in.cache.string().size(), cache.string());
      pids.push_back(test::start_command(cmd + " > " + (in.dir / ("log" + std::to_string(i))).string() + " 2>&1"));
    }
    for (int i = 0; i < 3; ++i) {
      const std::string where = "seed " + std::to_string(seed) + ", run " + std::to_string(i);
      EXPECT_EQ(test::wait_command(pids[size_t(i)]), 0) << where << "\n" << test::read_text(in.dir / ("log" + std::to_string(i)));
      expect_same_job(in.dir / ("s" + std::to_string(seed) + "-" + std::to_string(i)), want, where);
    }
    const auto damaged = test::damaged_entries(cache);
    EXPECT_TRUE(damaged.empty()) << damaged.front();
    const auto left = test::leftovers(cache_folder(cache));
    EXPECT_TRUE(left.empty()) << left.front();
    std::printf("seed %u: 3 runs started %d, %d and %d ms apart: %s\n", seed, offsets_ms[0], offsets_ms[1], offsets_ms[2],
                ::testing::Test::HasFailure() ? "FAILED" : "every output as a run alone, every cache entry whole");
  }
}

// Shards 0/2 and 1/2 of a batch, and a second copy of shard 0/2 (a resubmitted array task), at once, sharing
// one cache: every job's files equal a one-process batch's; the copy skips, is refused, or repeats a job, and
// then a one-process batch over the same file finds everything done.
TEST(ConcurrentJobs, BatchShardsAtOnceWriteWhatOneProcessWrites) {
  test::PipelineInputs in;
  auto jobs_file = [&](const std::string& root) {
    const fs::path f = in.dir / (root + ".jsonl");
    std::ofstream out(f);
    for (int i = 0; i < 2; ++i)
      out << nlohmann::json{{"prompt", "job " + std::to_string(i)}, {"seed", i}, {"out", (in.dir / root / ("job" + std::to_string(i))).string()}}.dump()
          << "\n";
    return f;
  };
  const std::string dvs = test::program("dvs") + " batch ";
  const auto one = test::run_command(dvs + jobs_file("one").string() + in.inputs() + " --quiet");
  ASSERT_EQ(one.exit_code, 0) << one.output;
  std::string inputs = in.inputs();
  inputs.replace(inputs.find(in.cache.string()), in.cache.string().size(), (in.dir / "shared-cache").string());
  const std::string sharded = dvs + jobs_file("sharded").string() + inputs + " --quiet";
  std::vector<int> pids;
  for (const char* shard : {"0/2", "1/2", "0/2"})
    pids.push_back(test::start_command(sharded + " --shard " + shard + " > " + (in.dir / ("shard" + std::to_string(pids.size()))).string() + " 2>&1"));
  // Processes 0 and 2 are the same command started together: either may take a job's folder first, so either may be
  // the one refused; at least one of them finishes cleanly.
  int clean_copies_of_shard_0 = 0;
  for (size_t i = 0; i < pids.size(); ++i) {
    const int rc = test::wait_command(pids[i]);
    const std::string log = test::read_text(in.dir / ("shard" + std::to_string(i)));
    if (i == 1) {
      EXPECT_EQ(rc, 0) << log;
    } else {
      clean_copies_of_shard_0 += rc == 0;
      EXPECT_TRUE(rc == 0 || log.find("in use by dvs process") != std::string::npos) << "a copy of shard 0/2\n" << log;
    }
    const size_t summary = log.rfind("dvs batch: shard");
    std::printf("shard process %zu: exit %d: %s", i, rc, (summary == std::string::npos ? log : log.substr(summary)).c_str());
  }
  EXPECT_GE(clean_copies_of_shard_0, 1) << "both copies of shard 0/2 failed";
  for (int i = 0; i < 2; ++i)
    expect_same_job(in.dir / "sharded" / ("job" + std::to_string(i)), test::visible_files(in.dir / "one" / ("job" + std::to_string(i))),
                    "job " + std::to_string(i));
  const auto damaged = test::damaged_entries(in.dir / "shared-cache");
  EXPECT_TRUE(damaged.empty()) << damaged.front();
  const auto again = test::run_command(sharded);
  EXPECT_NE(again.output.find("2 jobs: 0 done, 2 skipped (already done), 0 failed"), std::string::npos) << again.output;
}

}  // namespace
}  // namespace dvs
