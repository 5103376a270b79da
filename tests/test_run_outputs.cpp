// What a run leaves behind: a finished run's files survive a later run into the same --out that fails late
// (byte for byte, no staging left over); NaN produced on the device stops the run naming the stage, the tensor
// and the first bad index instead of writing a black video; a cached inversion holding NaN is not reused.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>

#include "io/npy.hpp"
#include "io/video.hpp"
#include "pipeline/cache_entry.hpp"
#include "support/files.hpp"
#include "support/model_edit.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

using test::PipelineInputs;

std::map<std::string, std::string> folder_bytes(const std::filesystem::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& name : test::files_in(dir)) files[name] = test::read_text(dir / name);
  return files;
}

TEST(RunOutputs, AFailingRunLeavesTheEarlierResultsIntact) {
  PipelineInputs in;
  const auto out = in.dir / "out";
  auto first = test::run_command(in.command(out));
  ASSERT_EQ(first.exit_code, 0) << first.output;
  const auto before = folder_bytes(out);
  for (const char* f : {"output.mp4", "render.mp4", "mask.mp4", "comparison.mp4", "run.json"})
    ASSERT_TRUE(before.count(f)) << f;

  // A staging folder left by a process that no longer exists (pid 2^22 + 1 exceeds Linux's PID_MAX_LIMIT, so it
  // is never alive) is cleaned up by the next run into the folder.
  const auto stale = out / ".dvs-partial-4194305-0";
  test::write_text(stale / "output.mp4", "half");
  // The same job with a decoder weight set to NaN: it runs every stage up to the VAE decode and fails there.
  const auto model = test::copy_model(in.model, in.dir / "nan_decoder");
  test::plant_nan(model, "vae", "decoder.conv_out.conv.weight", 5);
  std::string cmd = in.command(out, "--seed 3");
  cmd.replace(cmd.find(in.model.string()), in.model.string().size(), model.string());
  auto second = test::run_command(cmd);
  EXPECT_NE(second.exit_code, 0) << second.output;
  EXPECT_NE(second.output.find("decode stage: decoded frames [1,3,9,64,64]: "), std::string::npos) << second.output;
  EXPECT_NE(second.output.find("non-finite values (NaN/Inf), the first at [0,0,0,0,0]"), std::string::npos) << second.output;
  EXPECT_NE(second.output.find("\"stage\":\"sample\""), std::string::npos) << "it failed late, after sampling\n" << second.output;
  EXPECT_EQ(folder_bytes(out), before) << "the first run's files, byte for byte, and nothing else (no staging folder)";
  EXPECT_FALSE(std::filesystem::exists(stale)) << "a dead process's staging folder is removed";
}

TEST(RunOutputs, NanInTheTransformerStopsTheInversionAtItsFirstStep) {
  PipelineInputs in;
  const auto model = test::copy_model(in.model, in.dir / "nan_transformer");
  test::plant_nan(model, "transformer", "proj_out.bias", 0);
  std::string cmd = in.command(in.dir / "out");
  cmd.replace(cmd.find(in.model.string()), in.model.string().size(), model.string());
  auto r = test::run_command(cmd);
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("invert stage: transformer output at inversion step 1 (t="), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("dvs-weights inspect --values"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("\"stage\":\"sample\""), std::string::npos) << "stopped before the sampling\n" << r.output;
  EXPECT_FALSE(std::filesystem::exists(in.dir / "out")) << "the output folder this failed run created is removed again";

  // A folder that was there before the failed run stays, even empty.
  std::filesystem::create_directories(in.dir / "mine");
  cmd.replace(cmd.find((in.dir / "out").string()), (in.dir / "out").string().size(), (in.dir / "mine").string());
  r = test::run_command(cmd);
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::is_directory(in.dir / "mine"));
}

// dvs invert and dvs render fail the same way: the output folder they created is gone, one that was there stays.
TEST(RunOutputs, FailedInvertAndRenderRemoveTheFolderTheyCreated) {
  PipelineInputs in;
  const auto model = test::copy_model(in.model, in.dir / "nan_transformer");
  test::plant_nan(model, "transformer", "proj_out.bias", 0);
  std::string inputs = in.inputs();
  inputs.replace(inputs.find(in.model.string()), in.model.string().size(), model.string());
  auto inv = test::run_command(test::program("dvs") + " invert" + inputs + " --quiet --out " + (in.dir / "a" / "inv").string());
  EXPECT_EQ(inv.exit_code, 1) << inv.output;
  EXPECT_NE(inv.output.find("invert stage"), std::string::npos) << inv.output;
  EXPECT_FALSE(std::filesystem::exists(in.dir / "a")) << "both folders the failed inversion created are removed";

  // Metric depth with a negative value: the render stage refuses it after the output folder was made.
  HostTensor depth = read_npy(in.depth);
  depth.as<float>()[7] = -1.0f;
  write_npy(in.dir / "bad_depth.npy", depth);
  const std::string render = test::program("dvs") + " render --video " + in.video.string() + " --depth " +
                             (in.dir / "bad_depth.npy").string() + " --metric-depth --size 64x64 --frames 9 --quiet --out ";
  auto r = test::run_command(render + (in.dir / "r").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_FALSE(std::filesystem::exists(in.dir / "r")) << r.output;
  std::filesystem::create_directories(in.dir / "mine");
  r = test::run_command(render + (in.dir / "mine").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_TRUE(std::filesystem::is_directory(in.dir / "mine"));
}

// A cache folder that cannot be written: said once, even with --progress none; the run goes on uncached and
// run.json says so ("cache": false and why), instead of claiming a cache it did not use.
TEST(RunOutputs, AnUnwritableCacheIsSaidAndRecorded) {
  PipelineInputs in;
  test::write_text(in.dir / "a_file", "x");
  std::string cmd = in.command(in.dir / "out");
  cmd.replace(cmd.find("--progress json"), 15, "--progress none");
  cmd.replace(cmd.find(in.cache.string()), in.cache.string().size(), (in.dir / "a_file" / "cache").string());
  const auto r = test::run_command(cmd);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::string warning = "warning: the cache cannot be written, so this run is not cached";
  const size_t at = r.output.find(warning);
  EXPECT_NE(at, std::string::npos) << r.output;
  EXPECT_EQ(r.output.find(warning, at + 1), std::string::npos) << "said once\n" << r.output;
  EXPECT_NE(r.output.find("a_file"), std::string::npos) << r.output;
  const auto record = nlohmann::json::parse(std::ifstream(in.dir / "out" / "run.json"));
  EXPECT_EQ(record["settings"]["cache"], false);
  EXPECT_TRUE(record["settings"]["cache_dir"].is_null());
  EXPECT_NE(record.value("cache_problem", "").find("a_file"), std::string::npos) << record.dump(1);
  EXPECT_TRUE(record["latent"].is_null());
}

TEST(RunOutputs, ACachedInversionHoldingNanIsNotReused) {
  PipelineInputs in;
  auto r = test::run_command(in.command(in.dir / "a"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::vector<std::filesystem::path> cached;
  for (const auto& e : std::filesystem::recursive_directory_iterator(in.cache))
    if (e.path().filename().string().rfind("eps_inv-", 0) == 0 && e.path().extension() == ".npy")
      cached.push_back(e.path());  // not the latent, not the entry's commit marker
  ASSERT_EQ(cached.size(), 1u);
  HostTensor eps = read_npy(cached[0]);
  eps.as<float>()[7] = std::numeric_limits<float>::quiet_NaN();
  write_cache_entry(cached[0], eps);  // a whole entry (its marker matches) that holds a NaN

  // --progress none hides progress, not warnings: the entry being replaced is said on stderr all the same.
  std::string quiet = in.command(in.dir / "b", "--seed 5");
  quiet.replace(quiet.find("--progress json"), 15, "--progress none");
  r = test::run_command(quiet);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("ignoring the cached inversion"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1 non-finite values (NaN/Inf), the first at flat index 7"), std::string::npos) << r.output;
  auto record = nlohmann::json::parse(std::ifstream(in.dir / "b" / "run.json"));
  EXPECT_FALSE(record["inversion_from_cache"].get<bool>());
  HostTensor again = read_npy(cached[0]);  // inverted again and stored again: finite
  for (int64_t i = 0; i < again.numel(); ++i) ASSERT_TRUE(std::isfinite(again.as<float>()[i])) << i;
}

}  // namespace
}  // namespace dvs
