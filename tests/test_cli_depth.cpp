// `dvs depth` and `--depth-model` (dvs render / run), run as a user runs them, with the Video-Depth-Anything
// conformance pack's tiny checkpoint on the synthetic 64x64 scene: the file holds exactly what the driver computes
// for the options given (each option changes it), render estimates once and then reads the cache, and the same
// depth given with --depth renders the same mask; problems are named before any work.
#include <gtest/gtest.h>

#include <signal.h>

#include <chrono>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <thread>

#include "io/depth.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "models/vda/vda_model.hpp"
#include "models/vda/vda_video.hpp"
#include "support/files.hpp"
#include "support/gpu.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"
#include "support/pth_edit.hpp"
#include "support/vda_pack.hpp"

namespace dvs {
namespace {

class CliDepth : public test::GpuTest {};

std::string depth_cmd(const test::PipelineInputs& in, const std::filesystem::path& out, const std::string& extra) {
  return test::program("dvs") + " depth --quiet --video " + in.video.string() + " --depth-model " +
         test::vda_checkpoint_path().string() + " --out " + out.string() + " " + extra;
}

TEST_F(CliDepth, WritesWhatTheDriverComputesForTheOptionsGiven) {
  test::PipelineInputs in;
  const auto npz = in.dir / "d.npz", npz42 = in.dir / "d42.npz";
  auto r = test::run_command(depth_cmd(in, npz, "--input-size 28 --frames 7"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const HostTensor got = read_depth_array(npz);  // key "depths"
  ASSERT_EQ(got.dtype, DType::f32);
  ASSERT_EQ(got.shape, (Shape{7, 64, 64}));

  VdaModel model = VdaModel::load(ctx(), test::vda_checkpoint_path());
  const HostTensor frames = read_video_rgb8(in.video, 7, 1280);
  VdaVideoOptions o;
  o.input_size = 28;
  const HostTensor want = vda_video_depth(model, frames, o).depth;
  EXPECT_EQ(got.data, want.data) << "dvs depth differs from the driver run in-process";

  r = test::run_command(depth_cmd(in, npz42, "--input-size 42 --frames 7"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(read_depth_array(npz42).data, got.data) << "--input-size changed nothing";
  r = test::run_command(depth_cmd(in, in.dir / "all.npy", "--input-size 28"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(read_npy(in.dir / "all.npy").shape, (Shape{9, 64, 64})) << "without --frames every frame";
}

TEST_F(CliDepth, RenderEstimatesOnceThenReadsTheCacheAndMatchesTheSameDepthGivenAsAFile) {
  test::PipelineInputs in;
  const std::string common = test::program("dvs") + " render --video " + in.video.string() +
                             " --frames 9 --size 64x64 --no-glb --cache-dir " + in.cache.string();
  const std::string model = " --depth-model " + test::vda_checkpoint_path().string() + " --depth-input-size 28";
  auto first = test::run_command(common + model + " --out " + (in.dir / "o1").string());
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_NE(first.output.find("depth estimated"), std::string::npos) << first.output;
  auto second = test::run_command(common + model + " --out " + (in.dir / "o2").string());
  ASSERT_EQ(second.exit_code, 0) << second.output;
  EXPECT_NE(second.output.find("depth from the cache"), std::string::npos) << second.output;
  auto other = test::run_command(common + " --depth-model " + test::vda_checkpoint_path().string() +
                                 " --depth-input-size 42 --out " + (in.dir / "o4").string());
  ASSERT_EQ(other.exit_code, 0) << other.output;
  EXPECT_NE(other.output.find("depth estimated"), std::string::npos) << "another input size is another entry";

  auto d = test::run_command(depth_cmd(in, in.dir / "d.npz", "--input-size 28 --frames 9"));
  ASSERT_EQ(d.exit_code, 0) << d.output;
  auto given = test::run_command(common + " --depth " + (in.dir / "d.npz").string() + " --out " + (in.dir / "o3").string());
  ASSERT_EQ(given.exit_code, 0) << given.output;
  const HostTensor m1 = read_npy(in.dir / "o1" / "mask.npy"), m2 = read_npy(in.dir / "o2" / "mask.npy"),
                   m3 = read_npy(in.dir / "o3" / "mask.npy"), m4 = read_npy(in.dir / "o4" / "mask.npy");
  EXPECT_EQ(m1.data, m2.data);
  EXPECT_EQ(m1.data, m3.data) << "--depth-model and --depth of the same estimate render differently";
  EXPECT_NE(m1.data, m4.data) << "--depth-input-size was not applied";
}

// dvs run: the estimate is recorded in run.json (model, input size, cache file) and --from replays it with
// --depth-model again (found in the cache).
TEST_F(CliDepth, RunRecordsTheEstimateAndReplaysIt) {
  test::PipelineInputs in;
  const std::string run = test::program("dvs") + " run --video " + in.video.string() + " --depth-model " +
                          test::vda_checkpoint_path().string() + " --depth-input-size 28 --model " + in.model.string() +
                          " --frames 9 --size 64x64 --steps 4 --inversion-steps 3 --prompt 'a red fox' --quiet --cache-dir " +
                          in.cache.string();
  auto r = test::run_command(run + " --out " + (in.dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto record = nlohmann::json::parse(std::ifstream(in.dir / "out" / "run.json"));
  EXPECT_EQ(record["inputs"]["depth_model"], std::filesystem::absolute(test::vda_checkpoint_path()).lexically_normal().string());
  EXPECT_EQ(record["inputs"]["depth_input_size"], 28);
  ASSERT_TRUE(record["depth_estimate"].is_object()) << record.dump(1);
  EXPECT_FALSE(record["depth_estimate"]["from_cache"].get<bool>());
  const HostTensor cached = read_npy(record["depth_estimate"]["file"].get<std::string>());
  EXPECT_EQ(cached.shape, (Shape{9, 64, 64}));
  EXPECT_EQ(record["inputs"]["depth"], record["depth_estimate"]["file"]);

  auto again = test::run_command(test::program("dvs") + " run --quiet --from " + (in.dir / "out" / "run.json").string() +
                                 " --out " + (in.dir / "out2").string());
  ASSERT_EQ(again.exit_code, 0) << again.output;
  const auto record2 = nlohmann::json::parse(std::ifstream(in.dir / "out2" / "run.json"));
  EXPECT_TRUE(record2["depth_estimate"]["from_cache"].get<bool>()) << record2.dump(1);
  EXPECT_EQ(record2["inputs"]["depth"], record["inputs"]["depth"]);
  EXPECT_EQ(record2["inputs"]["depth_input_size"], 28);
}

// depth_cmd with JSON progress events instead of --quiet.
std::string depth_json_cmd(const test::PipelineInputs& in, const std::filesystem::path& out, const std::string& extra) {
  std::string c = depth_cmd(in, out, extra);
  return c.replace(c.find(" --quiet"), 8, " --progress json");
}

size_t npy_files_below(const std::filesystem::path& dir) {
  size_t n = 0;
  std::error_code ec;
  if (std::filesystem::exists(dir))
    for (const auto& e : std::filesystem::recursive_directory_iterator(dir, ec)) n += e.path().extension() == ".npy";
  return n;
}

// An --out that cannot be written is found before the estimate (no progress event), with the right hint; a
// missing folder is made; the estimate goes through the depth cache that --depth-model reads, so a retry with
// another --out, and render --depth-model with the same settings, reuse it.
TEST_F(CliDepth, OutputIsCheckedFirstAndTheEstimateIsCachedForEveryone) {
  test::PipelineInputs in;
  test::write_text(in.dir / "file", "x");
  const std::string opts = " --input-size 28 --frames 9 --cache-dir " + in.cache.string();
  auto bad = test::run_command(depth_json_cmd(in, in.dir / "file" / "d.npz", opts));
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  EXPECT_NE(bad.output.find("is not a folder"), std::string::npos) << bad.output;
  EXPECT_EQ(bad.output.find("disk"), std::string::npos) << "the wrong hint:\n" << bad.output;
  EXPECT_EQ(bad.output.find("\"stage\":\"depth\""), std::string::npos) << "estimated before checking --out:\n" << bad.output;
  EXPECT_EQ(npy_files_below(in.cache), 0u);

  auto first = test::run_command(depth_json_cmd(in, in.dir / "new" / "d.npz", opts));
  ASSERT_EQ(first.exit_code, 0) << first.output;
  EXPECT_NE(first.output.find("\"stage\":\"depth\""), std::string::npos) << first.output;
  EXPECT_EQ(npy_files_below(in.cache), 1u) << "dvs depth did not keep its estimate in the depth cache";
  auto retry = test::run_command(depth_json_cmd(in, in.dir / "new" / "e.npy", opts));
  ASSERT_EQ(retry.exit_code, 0) << retry.output;
  EXPECT_EQ(retry.output.find("\"stage\":\"depth\""), std::string::npos) << "estimated again:\n" << retry.output;
  EXPECT_NE(retry.output.find("from the depth cache"), std::string::npos) << retry.output;
  EXPECT_EQ(read_depth_array(in.dir / "new" / "e.npy").data, read_depth_array(in.dir / "new" / "d.npz").data);
  auto render = test::run_command(test::program("dvs") + " render --video " + in.video.string() + " --frames 9 --size 64x64 " +
                                  "--no-glb --depth-model " + test::vda_checkpoint_path().string() +
                                  " --depth-input-size 28 --cache-dir " + in.cache.string() + " --out " + (in.dir / "o").string());
  ASSERT_EQ(render.exit_code, 0) << render.output;
  EXPECT_NE(render.output.find("depth from the cache"), std::string::npos) << render.output;
}

// A valid .pth whose weights are NaN: an error naming the model and how to find the cause, exit 1, no depth
// file and nothing in the cache (a later run must not find a zero estimate there).
TEST_F(CliDepth, NaNWeightsAreAnErrorAndNothingIsCached) {
  test::PipelineInputs in;
  const auto nan_model = in.dir / "video_depth_anything_nan.pth";
  std::filesystem::copy_file(test::vda_golden_path() / "model" / "config.json", in.dir / "config.json");  // its size
  test::write_pth_filled(test::vda_checkpoint_path(), nan_model, "pretrained.blocks.0.attn.qkv.weight",
                         std::numeric_limits<float>::quiet_NaN());
  auto r = test::run_command(test::program("dvs") + " depth --quiet --video " + in.video.string() + " --depth-model " +
                             nan_model.string() + " --input-size 28 --frames 9 --cache-dir " + in.cache.string() +
                             " --out " + (in.dir / "d.npz").string());
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("video_depth_anything_nan.pth"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("inspect --values"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(in.dir / "d.npz"));
  EXPECT_EQ(npy_files_below(in.cache), 0u) << "the broken estimate was cached";
}

// Ctrl-C inside a window, in dvs depth and in render --depth-model: acknowledged at once ("stopping…"),
// honoured at the next step (seconds, not the window's end), exit 130, nothing written.
TEST_F(CliDepth, CtrlCInsideAWindowIsAcknowledgedAndHonoured) {
  test::PipelineInputs in;
  const auto log = in.dir / "log.txt";
  const std::string depth = depth_json_cmd(in, in.dir / "d.npz", "--input-size 252 --cache-dir " + in.cache.string());
  const std::string render = test::program("dvs") + " render --video " + in.video.string() + " --frames 9 --size 64x64 " +
                             "--no-glb --depth-model " + test::vda_checkpoint_path().string() + " --depth-input-size 252 " +
                             "--cache-dir " + in.cache.string() + " --out " + (in.dir / "o").string();
  // The first step inside the window, as each command reports it.
  for (const auto& [cmd, first_step] : {std::pair{depth, std::string("\"stage\":\"depth\",\"step\":1,")},
                                        std::pair{render, std::string("depth: step 1/")}}) {
    // An estimate long enough to interrupt needs a window buffer larger than the CI pass's forced allocation
    // limit: this test is about Ctrl-C, so it runs on the device's own limits.
    const int pid = test::start_command("env -u DVS_LIMITS " + cmd + " > " + log.string() + " 2>&1");
    ASSERT_GT(pid, 0);
    bool started = false, failed = false;
    for (int i = 0; i < 12000 && !started && !failed; ++i) {  // up to two minutes for the first step
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      const std::string text = test::read_text(log);
      started = text.find(first_step) != std::string::npos;
      failed = text.find("error") != std::string::npos;  // stopped before its first step: say why at once
    }
    ASSERT_TRUE(started) << test::read_text(log);
    const auto t = std::chrono::steady_clock::now();
    kill(pid, SIGINT);
    EXPECT_EQ(test::wait_command(pid), 130) << test::read_text(log);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
    const std::string output = test::read_text(log);
    EXPECT_NE(output.find("stopping"), std::string::npos) << output;
    EXPECT_LT(seconds, 30.0) << "Ctrl-C waited for the window to end";
    EXPECT_FALSE(std::filesystem::exists(in.dir / "d.npz"));
    EXPECT_FALSE(std::filesystem::exists(in.dir / "o" / "render.mp4"));
    EXPECT_EQ(npy_files_below(in.cache), 0u);
  }
}

TEST(CliDepthErrors, ProblemsAreNamedBeforeAnyWork) {
  test::PipelineInputs in;
  const std::string dvs = test::program("dvs");
  auto both = test::run_command(dvs + " render --video " + in.video.string() + " --depth " + in.depth.string() +
                                " --depth-model " + test::vda_checkpoint_path().string() + " --out " + (in.dir / "o").string());
  EXPECT_EQ(both.exit_code, 2) << both.output;
  auto neither = test::run_command(dvs + " render --video " + in.video.string() + " --out " + (in.dir / "o").string());
  EXPECT_EQ(neither.exit_code, 2) << neither.output;
  EXPECT_NE(neither.output.find("--depth-model"), std::string::npos) << neither.output;
  auto missing = test::run_command(dvs + " depth --video " + in.video.string() + " --depth-model " +
                                   (in.dir / "nope.pth").string() + " --out " + (in.dir / "d.npz").string());
  EXPECT_EQ(missing.exit_code, 1) << missing.output;
  EXPECT_NE(missing.output.find("nope.pth"), std::string::npos) << missing.output;
  const auto junk = in.dir / "junk.pth";
  test::write_text(junk, "not a zip at all");
  auto corrupt = test::run_command(dvs + " depth --video " + in.video.string() + " --depth-model " + junk.string() +
                                   " --out " + (in.dir / "d.npz").string());
  EXPECT_EQ(corrupt.exit_code, 1) << corrupt.output;
  EXPECT_NE(corrupt.output.find("junk.pth"), std::string::npos) << corrupt.output;
  EXPECT_FALSE(std::filesystem::exists(in.dir / "d.npz")) << "a failed estimate left a file";
  auto bad_out = test::run_command(dvs + " depth --video " + in.video.string() + " --depth-model " +
                                   test::vda_checkpoint_path().string() + " --out " + (in.dir / "d.txt").string());
  EXPECT_EQ(bad_out.exit_code, 2) << bad_out.output;
  // Another model's weights are named as such, by dvs depth and by the preflight.
  const auto transformer = test::golden_path() / "model" / "transformer" / "diffusion_pytorch_model.safetensors";
  auto wrong = test::run_command(dvs + " depth --video " + in.video.string() + " --depth-model " + transformer.string() +
                                 " --out " + (in.dir / "d.npz").string());
  EXPECT_EQ(wrong.exit_code, 1) << wrong.output;
  EXPECT_NE(wrong.output.find("not a Video-Depth-Anything checkpoint"), std::string::npos) << wrong.output;
  auto wrong_run = test::run_command(dvs + " run --check --video " + in.video.string() + " --depth-model " + transformer.string() +
                                     " --model " + in.model.string() + " --prompt x --frames 9 --size 64x64 --out " +
                                     (in.dir / "r").string());
  EXPECT_EQ(wrong_run.exit_code, 1) << wrong_run.output;
  EXPECT_NE(wrong_run.output.find("not a Video-Depth-Anything checkpoint"), std::string::npos) << wrong_run.output;
  // run: a corrupt depth model is found by the preflight (no model load, no device work).
  auto run = test::run_command(dvs + " run --check --video " + in.video.string() + " --depth-model " + junk.string() +
                               " --model " + in.model.string() + " --prompt x --frames 9 --size 64x64 --out " +
                               (in.dir / "r").string());
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_NE(run.output.find("junk.pth"), std::string::npos) << run.output;
}

}  // namespace
}  // namespace dvs
