// Injected faults walked over every stage of `dvs run` (tiny random model, --depth-model so the depth stage
// runs too): in each stage one device allocation, picked with a fixed seed, failed (VK_ERROR_OUT_OF_DEVICE_MEMORY),
// the same for queue submissions (VK_ERROR_DEVICE_LOST), and every file write failed with ENOSPC, every
// stage's first with EIO. Each: exit status 1 with one message naming the stage (device faults) or the file
// (writes) and the cause, nothing in --out, no torn cache entry, and the clean rerun succeeds and reuses what
// the cache held. Cache writes are the exception by design: a cache that cannot be written only costs time on
// a later run, so the run goes on (exit 0) without it. Prints the fault matrix (label robustness).
#include <gtest/gtest.h>

#include "dvs/cache.hpp"
#include "support/fault_walk.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/vda_pack.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
using test::FaultEvent;
using test::FaultOutcome;

struct RunCase {
  fs::path dir, out, cache;
};

class FaultsRun : public ::testing::Test {
 protected:
  test::PipelineInputs in;
  int cases = 0;

  RunCase fresh_case() {
    RunCase c;
    c.dir = in.dir / ("case-" + std::to_string(cases++));
    c.out = c.dir / "out";
    c.cache = c.dir / "cache";
    fs::create_directories(c.dir);
    return c;
  }

  std::string command(const RunCase& c, const std::string& env) const {
    // --cache-dir also holds the Vulkan pipeline cache (pipelines-*.bin), whose failed write only costs start-up time.
    return env + " " + test::program("dvs") + " run --video " +
           in.video.string() + " --depth-model " + test::vda_checkpoint_path().string() +
           " --depth-input-size 28 --model " + in.model.string() +
           " --frames 9 --size 64x64 --steps 4 --inversion-steps 3 --prompt 'a red fox' --progress json --cache-dir " +
           c.cache.string() + " --out " + c.out.string();
  }
};

std::string cache_entries(const fs::path& cache) {
  std::string s;
  for (const auto& name : test::files_in(cache_folder(cache))) {
    const std::string kind = name.substr(0, name.find('-'));
    if (s.find(kind) == std::string::npos) s += (s.empty() ? "" : "+") + kind;
  }
  return s.empty() ? "nothing" : s;
}

TEST_F(FaultsRun, EveryStageAndKindFailsCleanlyAndTheRerunReuses) {
  // The clean run's trace: every counted event and its stage.
  const RunCase traced = fresh_case();
  const fs::path trace = traced.dir / "trace.txt";
  const auto clean = test::run_command(command(traced, "DVS_FAULTS_TRACE=" + trace.string()));
  ASSERT_EQ(clean.exit_code, 0) << clean.output;
  const std::vector<FaultEvent> events = test::read_fault_trace(trace);
  std::set<std::string> stages;
  for (const auto& e : events) stages.insert(e.stage);
  for (const char* s : {"depth", "render", "encode", "text", "invert", "init_noise", "sample", "decode", "write"})
    EXPECT_TRUE(stages.count(s)) << "no counted event in stage " << s;

  struct Fault {
    FaultEvent event;
    std::string errno_name;  // writes
  };
  std::vector<Fault> faults;
  for (const auto& e : test::pick_fault_events(events, "alloc", 23)) faults.push_back({e, ""});
  for (const auto& e : test::pick_fault_events(events, "submit", 23)) faults.push_back({e, ""});
  std::set<std::string> eio_stages;
  for (const auto& e : events) {
    if (e.kind != "write") continue;
    faults.push_back({e, "ENOSPC"});
    if (eio_stages.insert(e.stage).second) faults.push_back({e, "EIO"});
  }

  std::vector<FaultOutcome> matrix;
  for (const auto& f : faults) {
    const FaultEvent& e = f.event;
    const std::string spec = e.kind + "=" + std::to_string(e.n) + (f.errno_name.empty() ? "" : ":" + f.errno_name);
    SCOPED_TRACE("DVS_FAULTS=" + spec + " (stage " + e.stage + ": " + e.where + ")");
    const RunCase c = fresh_case();
    // The same events in the same order as the traced run: where a write goes differs only by the case folder.
    FaultEvent here = e;
    if (here.where.rfind(traced.dir.string(), 0) == 0) here.where = c.dir.string() + here.where.substr(traced.dir.string().size());
    const auto r = test::run_command(command(c, "DVS_FAULTS=" + spec));
    FaultOutcome row{spec, e.stage, e.where.substr(e.where.rfind('/') + 1), r.exit_code, test::error_line(r.output), ""};

    const bool cache_write = e.kind == "write" && test::writes_a_cache(here, c.cache, c.cache);
    const std::string written = fs::path(here.where).filename().string();
    if (cache_write) {
      EXPECT_EQ(r.exit_code, 0) << "a cache that cannot be written must not stop the run\n" << r.output;
      if (written.rfind("eps_inv-", 0) == 0 || written.rfind("latent-", 0) == 0) {  // an entry: said, never silent
        EXPECT_NE(r.output.find("could not be cached"), std::string::npos) << r.output;
      }
    } else {
      EXPECT_EQ(r.exit_code, 1) << r.output;
      EXPECT_EQ(test::count_of(r.output, "dvs: error: "), 1u) << r.output;
      test::expect_fault_message(here, f.errno_name, row.message, test::stage_words(e.stage));
      EXPECT_TRUE(test::files_in(c.out).empty()) << "--out holds something after a failed run";
      EXPECT_EQ(r.output.find(".dvs-partial"), std::string::npos) << "names the staging folder, gone by now\n" << r.output;
    }
    const auto torn = test::torn_files(c.cache);
    EXPECT_TRUE(torn.empty()) << torn.front();
    row.kept = "out: " + std::string(test::files_in(c.out).empty() ? "nothing" : "the run's files") +
               "; cache: " + cache_entries(c.cache);

    // The clean rerun finishes and takes from the cache what the failed run had finished.
    if (r.exit_code != 0) {
      const bool had_depth = cache_entries(c.cache).find("depth") != std::string::npos;
      const bool had_inversion = cache_entries(c.cache).find("eps_inv") != std::string::npos;
      const bool had_latent = cache_entries(c.cache).find("latent") != std::string::npos;
      const auto again = test::run_command(command(c, ""));
      ASSERT_EQ(again.exit_code, 0) << again.output;
      for (const char* f : {"output.mp4", "render.mp4", "mask.mp4", "comparison.mp4", "run.json"})
        EXPECT_TRUE(fs::is_regular_file(c.out / f)) << f;
      std::string reused;
      if (had_depth) {
        EXPECT_NE(again.output.find("reading the cached estimate of"), std::string::npos) << again.output;
        reused += " depth";
      }
      if (had_latent) {
        EXPECT_NE(again.output.find("\"stage\":\"latent\""), std::string::npos) << again.output;
        reused += " latent";
      } else if (had_inversion) {
        EXPECT_TRUE(nlohmann::json::parse(test::read_text(c.out / "run.json"))["inversion_from_cache"].get<bool>());
        reused += " inversion";
      }
      row.kept += "; rerun: exit 0, reused" + (reused.empty() ? std::string(" nothing") : reused);
    }
    matrix.push_back(row);
    fs::remove_all(c.dir);
  }
  test::print_fault_matrix("dvs run (tiny model, --depth-model, 9 frames 64x64, 4 steps)", matrix);
}

// A switch that cannot be read stops the program at once, naming the variable and the forms it takes.
TEST(FaultsSwitch, AMalformedSwitchIsNamed) {
  test::TempDir dir;
  for (const char* spec : {"bogus", "alloc=0", "write=3", "write=3:EFAULT", "submit=x"}) {
    const auto r = test::run_command(std::string("DVS_FAULTS=") + spec + " " + test::program("dvs") + " demo --quiet --out " +
                                     (dir.path / "out").string());
    EXPECT_EQ(r.exit_code, 1) << spec << "\n" << r.output;
    EXPECT_NE(r.output.find("DVS_FAULTS: '" + std::string(spec) + "' is not one of alloc=N, submit=N, write=N:ENOSPC"),
              std::string::npos) << r.output;
  }
}

}  // namespace
}  // namespace dvs
