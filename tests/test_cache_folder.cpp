// One meaning for the cache folder (issue 34 §2 item 5): `--cache-dir DIR`, `DVS_CACHE_DIR=DIR` and the library's
// DepthJob::cache_dir all name DIR, whose inversions/ holds the entries and which holds the pipeline cache. Before,
// the variable meant DIR/inversions and the option DIR itself, so a run given the option recomputed a depth estimate
// the variable's run had cached (15 minutes at the real size). An earlier layout (entries directly in DIR) is refused
// with the commands that move it, never silently computed again. Run as a user runs dvs, with the conformance
// pack's tiny Video-Depth-Anything on the synthetic 64×64 scene.
#include <gtest/gtest.h>

#include <string>

#include "dvs/cache.hpp"
#include "dvs/depth_estimate.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"
#include "support/vda_pack.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

struct DepthCommand {
  test::PipelineInputs in;
  // dvs depth of the scene into `out`; `cache`: the words that name the cache folder (an option or a variable).
  std::string depth(const fs::path& out, const std::string& before, const std::string& after) const {
    return before + test::program("dvs") + " depth --progress json --video " + in.video.string() + " --depth-model " +
           test::vda_checkpoint_path().string() + " --input-size 28 --frames 9 --out " + out.string() + " " + after;
  }
};

size_t files_named(const fs::path& dir, const std::string& prefix, const std::string& extension) {
  size_t n = 0;
  for (const auto& name : test::files_in(dir))
    n += name.rfind(prefix, 0) == 0 && name.size() > extension.size() &&
         name.compare(name.size() - extension.size(), extension.size(), extension) == 0;
  return n;
}

TEST(CacheFolder, TheOptionTheVariableAndTheLibraryNameOneFolder) {
  DepthCommand c;
  const fs::path dir = c.in.dir / "cache";
  // 1. --cache-dir DIR: the estimate in DIR/inversions, the pipeline cache in DIR (where DVS_CACHE_DIR puts both).
  const auto first = test::run_command(c.depth(c.in.dir / "a.npz", "", "--cache-dir " + dir.string()));
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_NE(first.output.find("\"stage\":\"depth\""), std::string::npos) << first.output;
  EXPECT_EQ(files_named(dir / "inversions", "depth-", ".npy"), 1u) << "the estimate is not in DIR/inversions";
  EXPECT_EQ(files_named(dir, "depth-", ".npy"), 0u) << "an entry directly in DIR";
  EXPECT_EQ(files_named(dir, "pipelines-", ".bin"), 1u) << "the pipeline cache is not in DIR";
  // 2. DVS_CACHE_DIR=DIR finds it.
  const auto by_variable = test::run_command(c.depth(c.in.dir / "b.npz", "DVS_CACHE_DIR=" + dir.string() + " ", ""));
  ASSERT_EQ(by_variable.exit_code, 0) << by_variable.output;
  EXPECT_NE(by_variable.output.find("from the depth cache"), std::string::npos) << "estimated again:\n" << by_variable.output;
  // 3. So does the library's DepthJob::cache_dir = DIR.
  DepthJob job;
  job.video = c.in.video;
  job.model = test::vda_checkpoint_path();
  job.input_size = 28;
  job.frames = 9;
  job.cache_dir = dir;
  EXPECT_TRUE(estimate_depth(job, c.in.dir / "c.npz").from_cache) << "the library's cache_dir estimated again";
  EXPECT_EQ(files_named(dir / "inversions", "depth-", ".npy"), 1u);
}

TEST(CacheFolder, AnEarlierLayoutIsRefusedWithTheCommandsThatMoveIt) {
  DepthCommand c;
  const fs::path made = c.in.dir / "made", old = c.in.dir / "old";
  ASSERT_EQ(test::run_command(c.depth(c.in.dir / "a.npz", "", "--cache-dir " + made.string())).exit_code, 0);
  fs::rename(made / "inversions", old);  // the entries directly in the folder, as --cache-dir used to keep them

  const auto refused = test::run_command(c.depth(c.in.dir / "b.npz", "", "--cache-dir " + old.string()));
  EXPECT_EQ(refused.exit_code, 1) << refused.output;
  EXPECT_EQ(refused.output.find("\"stage\":\"depth\""), std::string::npos) << "estimated again:\n" << refused.output;
  EXPECT_FALSE(fs::exists(c.in.dir / "b.npz"));
  const std::string marker = "Move them there to keep them: ";
  const size_t at = refused.output.find(marker);
  ASSERT_NE(at, std::string::npos) << refused.output;
  EXPECT_NE(refused.output.find(old.string() + ": the cache folder holds 2 entry files directly in it"), std::string::npos)
      << refused.output;
  // The checks before any work say it too (render --depth-model --check reads the same cache).
  const auto check = test::run_command(test::program("dvs") + " render --video " + c.in.video.string() +
                                       " --frames 9 --size 64x64 --depth-model " + test::vda_checkpoint_path().string() +
                                       " --depth-input-size 28 --cache-dir " + old.string() + " --out " +
                                       (c.in.dir / "o").string() + " --check");
  EXPECT_EQ(check.exit_code, 1) << check.output;
  EXPECT_NE(check.output.find("--depth-model: " + old.string() + ": the cache folder holds"), std::string::npos) << check.output;

  // The commands as printed (up to the end of the message's line) put the entries in place: the estimate is found.
  std::string move = refused.output.substr(at + marker.size());
  move = move.substr(0, move.find_first_of("\"\n"));
  ASSERT_EQ(test::run_command(move).exit_code, 0) << move;
  const auto found = test::run_command(c.depth(c.in.dir / "b.npz", "", "--cache-dir " + old.string()));
  ASSERT_EQ(found.exit_code, 0) << found.output;
  EXPECT_NE(found.output.find("from the depth cache"), std::string::npos) << found.output;
}

}  // namespace
}  // namespace dvs
