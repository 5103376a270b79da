// Injected faults walked over `dvs depth` and `dvs invert` (the VDA conformance checkpoint, the tiny random
// CogVideoX model): per stage the first device allocation failed (out of device memory) and the first queue
// submission lost, and every file write failed with ENOSPC (the first per stage with EIO too). Each: exit status 1
// with one message naming the stage or the file and the cause, nothing at --out, no torn cache entry; the clean
// rerun succeeds and takes the finished estimate or inversion from the cache. A failed write into a cache (the
// inversion cache, the pipeline cache) does not stop the command (exit 0). Prints the fault matrix (label
// robustness).
#include <gtest/gtest.h>

#include <functional>

#include "dvs/cache.hpp"
#include "support/fault_walk.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/vda_pack.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
using test::FaultEvent;
using test::FaultOutcome;

struct Walk {
  std::string name;  // "depth", "invert"
  // The command writing into `dir` (its out, its cache), with `env` before it.
  std::function<std::string(const fs::path& dir, const std::string& env)> command;
  std::function<bool(const fs::path& dir)> output_written;
  std::string reuse_words;     // what the rerun says when it takes the entry from the cache
  std::string stage_prefix;    // how a device fault's message names its stage; "": "<stage> stage: "
};

// Faults: per (device kind, stage) the first event; every write with ENOSPC; each stage's first write with EIO.
std::vector<std::pair<FaultEvent, std::string>> faults_of(const std::vector<FaultEvent>& events) {
  std::vector<std::pair<FaultEvent, std::string>> faults;
  std::set<std::string> seen;
  for (const auto& e : events) {
    if (e.kind != "write") {
      if (seen.insert(e.kind + " " + e.stage).second) faults.push_back({e, ""});
      continue;
    }
    faults.push_back({e, "ENOSPC"});
    if (seen.insert("EIO " + e.stage).second) faults.push_back({e, "EIO"});
  }
  return faults;
}

std::vector<FaultOutcome> walk(const Walk& w, const fs::path& root, const fs::path& pipelines) {
  const fs::path traced = root / (w.name + "-trace");
  const auto clean = test::run_command(w.command(traced, "DVS_FAULTS_TRACE=" + (root / (w.name + ".trace")).string()));
  EXPECT_EQ(clean.exit_code, 0) << clean.output;
  const std::vector<FaultEvent> events = test::read_fault_trace(root / (w.name + ".trace"));
  EXPECT_FALSE(events.empty());
  std::vector<FaultOutcome> matrix;
  int n = 0;
  for (const auto& [e, errno_name] : faults_of(events)) {
    const std::string spec = e.kind + "=" + std::to_string(e.n) + (errno_name.empty() ? "" : ":" + errno_name);
    SCOPED_TRACE(w.name + ": DVS_FAULTS=" + spec + " (stage " + e.stage + ": " + e.where + ")");
    const fs::path dir = root / (w.name + "-" + std::to_string(n++));
    const auto r = test::run_command(w.command(dir, "DVS_FAULTS=" + spec));
    FaultOutcome row{spec, e.stage, e.where.substr(e.where.rfind('/') + 1), r.exit_code, test::error_line(r.output), ""};
    const bool cache_write = e.kind == "write" && test::writes_a_cache(e, traced / "cache", pipelines);
    const auto torn = test::torn_files(dir / "cache");
    EXPECT_TRUE(torn.empty()) << torn.front();
    const bool cached = !test::files_in(cache_folder(dir / "cache")).empty();
    row.kept = std::string("out: ") + (w.output_written(dir) ? "written" : "nothing") + "; cache: " +
               (cached ? "the entry" : "nothing");
    if (cache_write) {  // only time is lost on a later run
      EXPECT_EQ(r.exit_code, 0) << r.output;
    } else {
      EXPECT_EQ(r.exit_code, 1) << r.output;
      EXPECT_EQ(test::count_of(r.output, "dvs: error: "), 1u) << r.output;
      test::expect_fault_message(e, errno_name, row.message, w.stage_prefix.empty() ? test::stage_words(e.stage) : w.stage_prefix);
      EXPECT_FALSE(w.output_written(dir)) << "a failed run left its output";
      EXPECT_EQ(r.output.find(".dvs-partial"), std::string::npos) << "names the staging folder, gone by now\n" << r.output;
      const auto again = test::run_command(w.command(dir, ""));
      EXPECT_EQ(again.exit_code, 0) << again.output;
      EXPECT_TRUE(w.output_written(dir));
      const bool reused = again.output.find(w.reuse_words) != std::string::npos;
      EXPECT_EQ(reused, cached) << "the rerun " << (cached ? "did not reuse" : "claims to reuse") << " the cache entry\n"
                                << again.output;
      row.kept += std::string("; rerun: exit ") + std::to_string(again.exit_code) + (reused ? ", reused the entry" : "");
    }
    matrix.push_back(row);
    fs::remove_all(dir);
  }
  return matrix;
}

TEST(FaultsDepthInvert, DepthAndInvertFailCleanlyAtEveryStage) {
  test::PipelineInputs in;
  const fs::path pipelines = in.dir / "pipelines";
  const std::string dvs = "DVS_CACHE_DIR=" + pipelines.string() + " ";
  Walk depth{"depth",
             [&](const fs::path& dir, const std::string& env) {
               return dvs + env + " " + test::program("dvs") + " depth --video " + in.video.string() + " --depth-model " +
                      test::vda_checkpoint_path().string() + " --input-size 28 --frames 9 --cache-dir " +
                      (dir / "cache").string() + " --out " + (dir / "out" / "d.npz").string();
             },
             [](const fs::path& dir) { return fs::is_regular_file(dir / "out" / "d.npz"); },
             "from the depth cache", "depth estimate: "};
  Walk invert{"invert",
              [&](const fs::path& dir, const std::string& env) {
                return dvs + env + " " + test::program("dvs") + " invert --video " + in.video.string() + " --depth " +
                       in.depth.string() + " --metric-depth --model " + in.model.string() +
                       " --frames 9 --size 64x64 --inversion-steps 3 --cache-dir " + (dir / "cache").string() +
                       " --out " + (dir / "out").string();
              },
              [](const fs::path& dir) { return !test::files_in(dir / "out").empty(); },
              "(inversion from the cache)", ""};
  const auto depth_rows = walk(depth, in.dir.path, pipelines);
  test::print_fault_matrix("dvs depth (VDA conformance checkpoint, 9 frames 64x64, --input-size 28)", depth_rows);
  const auto invert_rows = walk(invert, in.dir.path, pipelines);
  test::print_fault_matrix("dvs invert (tiny model, 9 frames 64x64, 3 inversion steps)", invert_rows);
}

}  // namespace
}  // namespace dvs
