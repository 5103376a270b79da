// The README's Slurm recipe (docs/examples/slurm_batch.sh) submitted as it is, its paths given through JOBS,
// MODEL and PATH, to a real single-node Slurm that tests/cluster/slurm_cluster.sh starts and always stops: its
// array tasks each run `dvs batch --shard I/N` (two at a time, sharing one cache folder) on the conformance
// pack's tiny model, and every job's outputs must equal, byte for byte, those of the same recipe run as one
// process (--shard 0/1). And the cluster script leaves nothing running, also when its command fails. Label
// "cluster". Without Slurm (not installed, not root, a daemon that does not start) the tests are skipped and say
// why; with DVS_REQUIRE_SLURM=1 (CI) that is a failure.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>

#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"
#include "support/source_dir.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

// slurm_cluster.sh's exit status when Slurm cannot start on this machine.
constexpr int kSlurmCannotStart = 77;
// The recipe's `#SBATCH --array=0-7`.
constexpr int kTasks = 8;
// More jobs than tasks, so some shards run two jobs in one process and others one.
constexpr int kJobs = 10;

bool slurm_required() {
  const char* e = std::getenv("DVS_REQUIRE_SLURM");
  return e && std::string(e) == "1";
}

fs::path cluster_script() { return test::source_dir() / "tests" / "cluster" / "slurm_cluster.sh"; }

// `slurm_cluster.sh WORK COMMAND` as this test runs it: setpriv ends the script (and with it the daemons) when
// this test process ends.
std::string on_cluster(const fs::path& work, const std::string& command) {
  return "setpriv --pdeathsig TERM bash " + cluster_script().string() + " " + work.string() + " " + command;
}

// Processes of the cluster slurm_cluster.sh ran in `work`: the daemons, job steps and their tasks all carry its
// SLURM_CONF in their environment.
std::vector<std::string> cluster_processes(const fs::path& work) {
  const std::string marker = "SLURM_CONF=" + (work / "slurm" / "slurm.conf").string();
  std::vector<std::string> found;
  std::error_code ec;
  for (fs::directory_iterator it("/proc", ec), end; !ec && it != end; it.increment(ec)) {
    const std::string pid = it->path().filename().string();
    if (pid.find_first_not_of("0123456789") != std::string::npos) continue;
    const std::string env = test::read_text(it->path() / "environ");  // NUL-separated NAME=VALUE entries
    for (size_t at = 0; at < env.size();) {
      const size_t end = std::min(env.find('\0', at), env.size());
      if (env.compare(at, end - at, marker) == 0) {
        std::string name = test::read_text(it->path() / "comm");
        found.push_back(pid + " " + name.substr(0, name.find('\n')));
        break;
      }
      at = end + 1;
    }
  }
  return found;
}

// The jobs file of both runs: relative out folders (the recipe's jobs start at the submission folder), the
// synthetic scene's video and depth, two camera paths (two inversions, each shared by several jobs: shards
// that run at once meet in the cache) and a seed and prompt of their own per job.
void write_jobs(const fs::path& file, const test::PipelineInputs& in) {
  std::ofstream f(file);
  for (int i = 0; i < kJobs; ++i) {
    nlohmann::json job{{"video", in.video.string()}, {"depth", in.depth.string()}, {"metric-depth", true},
                       {"frames", 9}, {"size", "64x64"}, {"steps", 4}, {"inversion-steps", 3},
                       {"trajectory", i % 2 ? "pan_left:5" : "loop1"}, {"prompt", "job " + std::to_string(i)},
                       {"seed", 100 + i}, {"out", "out/job" + std::to_string(i)}};
    f << job.dump() << "\n";
  }
}

// `cd DIR && JOBS=... MODEL=... PATH=<the build's programs>:$PATH ...`: the recipe's paths for this test.
std::string recipe_environment(const fs::path& dir, const test::PipelineInputs& in) {
  const fs::path programs = fs::path(test::program("dvs")).parent_path();
  return "cd " + dir.string() + " && JOBS=jobs.jsonl MODEL=" + in.model.string() + " DVS_CACHE_DIR=" +
         (dir / "cache").string() + " PATH=" + programs.string() + ":\"$PATH\" ";
}

// run.json without what differs between two runs of the same job in other folders (times, peak memory, the
// out and cache folders, whether the inversion came from the cache).
nlohmann::json comparable_record(const fs::path& run_json) {
  nlohmann::json j = nlohmann::json::parse(std::ifstream(run_json));
  j["inputs"].erase("out");
  j["settings"].erase("cache_dir");
  j["latent"].erase("path");
  for (const char* key : {"seconds", "seconds_total", "peak_device_bytes", "peak_host_bytes", "inversion_from_cache"})
    j.erase(key);
  return j;
}

TEST(SlurmArray, RecipeShardsMatchOneProcessBatch) {
  test::PipelineInputs in;
  const fs::path recipe = test::source_dir() / "docs" / "examples" / "slurm_batch.sh";
  ASSERT_TRUE(fs::exists(recipe)) << recipe;
  const fs::path one = in.dir / "one", slurm = in.dir / "slurm";
  for (const fs::path& d : {one, slurm}) {
    fs::create_directories(d);
    write_jobs(d / "jobs.jsonl", in);
  }

  // The array job. setpriv: the cluster script (and with it the daemons) ends when this test process does.
  // timeout: a task that hangs fails the test well within ctest's limit, and the script still stops Slurm.
  const auto submitted =
      test::run_command(recipe_environment(slurm, in) + on_cluster(slurm, "timeout 1500 sbatch --wait " + recipe.string()));
  if (submitted.exit_code == kSlurmCannotStart) {
    if (slurm_required()) FAIL() << "DVS_REQUIRE_SLURM=1 and Slurm could not start:\n" << submitted.output;
    GTEST_SKIP() << "Slurm cannot start on this machine (DVS_REQUIRE_SLURM=1 makes this a failure):\n"
                 << submitted.output;
  }

  for (const auto& p : cluster_processes(slurm)) ADD_FAILURE() << "left running after the cluster stopped: " << p;

  // The reference: the same script as one process, the whole file in one shard.
  auto single = test::run_command(recipe_environment(one, in) + "SLURM_ARRAY_TASK_ID=0 SLURM_ARRAY_TASK_COUNT=1 bash " +
                                  recipe.string());
  ASSERT_EQ(single.exit_code, 0) << single.output;
  ASSERT_NE(single.output.find("shard 0/1: " + std::to_string(kJobs) + " of " + std::to_string(kJobs) + " jobs: " +
                               std::to_string(kJobs) + " done"),
            std::string::npos)
      << single.output;

  // The array job's outcome.
  std::string logs;
  for (const auto& name : test::files_in(slurm))
    if (name.rfind("dvs-batch-", 0) == 0) logs += "--- " + name + "\n" + test::read_text(slurm / name);
  ASSERT_EQ(submitted.exit_code, 0) << submitted.output << "\n" << logs;
  EXPECT_NE(submitted.output.find("Submitted batch job"), std::string::npos) << submitted.output;

  // Every task's log (the recipe's --output=dvs-batch-%A_%a.log) ends with its shard's summary.
  std::smatch id;
  ASSERT_TRUE(std::regex_search(submitted.output, id, std::regex("Submitted batch job (\\d+)"))) << submitted.output;
  for (int task = 0; task < kTasks; ++task) {
    const fs::path log = slurm / ("dvs-batch-" + id[1].str() + "_" + std::to_string(task) + ".log");
    ASSERT_TRUE(fs::exists(log)) << "no log of array task " << task << "\n" << logs;
    const int mine = (kJobs - task + kTasks - 1) / kTasks;  // jobs whose index ≡ task (mod kTasks)
    const std::string summary = "dvs batch: shard " + std::to_string(task) + "/" + std::to_string(kTasks) + ": " +
                                std::to_string(mine) + " of " + std::to_string(kJobs) + " jobs: " + std::to_string(mine) +
                                " done, 0 skipped (already done), 0 failed";
    EXPECT_NE(test::read_text(log).find(summary), std::string::npos) << log << "\n" << test::read_text(log);
  }

  // Every job's outputs are there and equal to the one-process batch's.
  for (int job = 0; job < kJobs; ++job) {
    const std::string out = "out/job" + std::to_string(job);
    for (const char* file : {"output.mp4", "render.mp4", "mask.mp4", "comparison.mp4"}) {
      ASSERT_TRUE(fs::exists(slurm / out / file)) << out << "/" << file << " missing\n" << logs;
      EXPECT_TRUE(test::read_text(slurm / out / file) == test::read_text(one / out / file))
          << out << "/" << file << " differs from the one-process batch's";
    }
    const auto differences = nlohmann::json::diff(comparable_record(one / out / "run.json"),
                                                  comparable_record(slurm / out / "run.json"));
    EXPECT_TRUE(differences.empty()) << out << "/run.json differs from the one-process batch's: " << differences.dump();
  }
  for (const auto& name : test::files_in(slurm / "cache" / "inversions"))
    EXPECT_TRUE(name.find(".tmp-") == std::string::npos && name.find(".partial-") == std::string::npos)
        << "a cache file left half-written: " << name;
}

// The cluster is stopped when the command fails too: a job still running is cancelled, and no daemon, job step
// or task of it is left.
TEST(SlurmCluster, StopsEverythingWhenTheCommandFails) {
  test::TempDir work;
  const std::string command =
      "bash -c 'sbatch --output=/dev/null --wrap \"sleep 300\" || exit 10; "
      "for i in $(seq 100); do squeue -h -o %T | grep -q RUNNING && exit 3; sleep 0.2; done; exit 11'";
  const auto r = test::run_command(on_cluster(work.path, command));
  if (r.exit_code == kSlurmCannotStart) {
    if (slurm_required()) FAIL() << "DVS_REQUIRE_SLURM=1 and Slurm could not start:\n" << r.output;
    GTEST_SKIP() << "Slurm cannot start on this machine (DVS_REQUIRE_SLURM=1 makes this a failure):\n" << r.output;
  }
  EXPECT_EQ(r.exit_code, 3) << "the command's own exit status (10: sbatch failed, 11: the job never ran)\n" << r.output;
  EXPECT_NE(r.output.find("cancelling jobs still in the queue"), std::string::npos) << r.output;
  for (const auto& p : cluster_processes(work.path)) ADD_FAILURE() << "left running after the cluster stopped: " << p;
}

}  // namespace
}  // namespace dvs
