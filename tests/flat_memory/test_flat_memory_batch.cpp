// A long `dvs batch` stays flat: 12 small jobs in one process (the conformance pack's tiny model on the synthetic
// scene, every job the same work but its seed), its memory read from /proc/PID while it runs. After the second
// job nothing may grow: each job's peak host RSS (VmHWM, restarted as each job starts) stays within a bound of
// the second job's, and each job's device-memory peak (the allocator's, run.json's peak_device_bytes) is the
// same. Threads, open files and the RSS left between jobs are checked exactly by test_flat_memory_library.cpp,
// where the calls' ends are known; seen from outside, a job's end is only known to within a poll. Label
// "robustness".
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "flat_memory/process_memory.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

constexpr int kJobs = 12;

struct JobSample {
  test::ProcessMemory at_end;  // when the next job starts: this job's peak
  uint64_t device_peak = 0;    // run.json's peak_device_bytes
};

TEST(FlatMemory, BatchOfTwelveJobs) {
  test::PipelineInputs in;
  const fs::path jobs = in.dir / "jobs.jsonl", log = in.dir / "batch.log";
  {
    std::ofstream f(jobs);
    for (int i = 0; i < kJobs; ++i)
      f << nlohmann::json{{"prompt", "a red fox"}, {"seed", i}, {"out", (in.dir / ("out" + std::to_string(i))).string()}}.dump()
        << "\n";
  }
  const int pid = test::start_command("env " + std::string(test::kFixedMmapThreshold) + " " + test::program("dvs") + " batch " +
                                      jobs.string() + in.inputs() + " --progress none > " + log.string() + " 2>&1");
  ASSERT_GT(pid, 0);

  // Each "running" line starts a job: the one before it has ended, its context and models are gone.
  std::vector<JobSample> samples;
  bool reset_refused = false;
  int status = 0;
  const auto started = std::chrono::steady_clock::now();
  while (waitpid(pid, &status, WNOHANG) == 0) {
    const size_t running = test::count_of(test::read_text(log), ": running -> ");
    if (running > samples.size() + 1) {
      const test::ProcessMemory m = test::process_memory(pid);
      if (!m.valid) continue;
      samples.push_back({m, 0});
      reset_refused |= !test::reset_peak_rss(pid);
    }
    if (std::chrono::steady_clock::now() - started > std::chrono::minutes(15)) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      FAIL() << "the batch did not end within 15 minutes\n" << test::read_text(log);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const std::string output = test::read_text(log);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << output;
  ASSERT_NE(output.find(std::to_string(kJobs) + " of " + std::to_string(kJobs) + " jobs: " + std::to_string(kJobs) + " done"),
            std::string::npos)
      << output;
  ASSERT_FALSE(reset_refused) << "/proc/" << pid << "/clear_refs refused: the peaks would not be per job";
  // The last job ends with the process, so jobs 1..11 are sampled (a sample is missed only when a job ends
  // between two polls 5 ms apart, which a job of this size never does).
  ASSERT_EQ(samples.size(), size_t(kJobs - 1)) << output;
  for (size_t j = 0; j < samples.size(); ++j)
    samples[j].device_peak =
        nlohmann::json::parse(std::ifstream(in.dir / ("out" + std::to_string(j)) / "run.json"))["peak_device_bytes"];

  std::printf("job  peak RSS (MiB)  device peak (MiB)\n");
  for (size_t j = 0; j < samples.size(); ++j)
    std::printf("%3zu  %14.2f  %17.2f\n", j + 1, test::mib(samples[j].at_end.peak_rss_bytes), test::mib(samples[j].device_peak));
  const JobSample& second = samples[1];
  for (size_t j = 2; j < samples.size(); ++j) {
    const JobSample& s = samples[j];
    EXPECT_LE(s.at_end.peak_rss_bytes, second.at_end.peak_rss_bytes + test::kGrowthBound)
        << "job " << j + 1 << "'s peak RSS is " << test::mib(s.at_end.peak_rss_bytes - second.at_end.peak_rss_bytes)
        << " MiB over job 2's";
    EXPECT_EQ(s.device_peak, second.device_peak) << "device memory peak of job " << j + 1;
  }
}

}  // namespace
}  // namespace dvs
