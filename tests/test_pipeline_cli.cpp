// `dvs run` end to end on the synthetic scene with the conformance pack's tiny model (its positional table
// fixes the size: 9 frames of 64×64), as a user runs it.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "geometry/synthetic_scene.hpp"
#include "io/npy.hpp"
#include "io/safetensors_writer.hpp"
#include "io/video.hpp"
#include "support/lora_adapter.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

using test::PipelineInputs;

TEST(PipelineCli, RunWritesEveryOutputAndReusesTheInversion) {
  PipelineInputs in;
  auto out = in.dir / "out";
  auto r = test::run_command(in.command(out));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("\"stage\":\"sample\""), std::string::npos) << "JSON progress events";
  for (const char* f : {"output.mp4", "render.mp4", "mask.mp4", "comparison.mp4", "run.json"})
    EXPECT_TRUE(std::filesystem::exists(out / f)) << f;
  VideoInfo info;
  HostTensor output = read_video(out / "output.mp4", {}, &info);
  EXPECT_EQ(output.shape, (Shape{9, 3, 64, 64}));
  EXPECT_NEAR(info.fps, 10.0, 1e-3);
  HostTensor cmp = read_video(out / "comparison.mp4");
  EXPECT_EQ(cmp.shape, (Shape{9, 3, 64, 192}));
  auto run = nlohmann::json::parse(std::ifstream(out / "run.json"));
  for (const char* k : {"dvs_version", "device", "driver", "inputs", "settings", "seconds", "peak_device_bytes", "outputs"})
    EXPECT_TRUE(run.contains(k)) << k;
  EXPECT_EQ(run["settings"]["seed"], 42);
  EXPECT_EQ(run["settings"]["t0"], 749);  // 4 steps at strength 0.95: 749, 499, 249
  EXPECT_FALSE(run["inversion_from_cache"].get<bool>());
  EXPECT_GT(run["peak_device_bytes"].get<double>(), 0);

  auto again = test::run_command(in.command(in.dir / "out2", "--guidance 3 --seed 7"));
  ASSERT_EQ(again.exit_code, 0) << again.output;
  auto run2 = nlohmann::json::parse(std::ifstream(in.dir / "out2" / "run.json"));
  EXPECT_TRUE(run2["inversion_from_cache"].get<bool>());
}

TEST(PipelineCli, BadInputsFailClearlyAndWriteNothing) {
  PipelineInputs in;
  auto out = in.dir / "bad";
  // A model folder whose VAE weights are cut short: found only when the VAE loads, after the render.
  const auto broken_model = in.dir / "broken_model";
  std::filesystem::copy(in.model, broken_model, std::filesystem::copy_options::recursive);
  for (const auto& e : std::filesystem::directory_iterator(broken_model / "vae"))
    if (e.path().extension() == ".safetensors") std::filesystem::resize_file(e.path(), std::filesystem::file_size(e.path()) / 2);
  test::write_text(in.dir / "empty.mp4", "");
  test::write_text(in.dir / "garbage.mp4", std::string(4096, 'x'));
  test::write_text(in.dir / "a_file", "x");
  test::PipelineInputs::write_scene_depth(in.dir / "depth5.npy", 5);
  struct Case {
    std::string extra, expect;
  } cases[] = {
      {"--frames 8", "4k+1"},
      {"--preset fancy", "--preset"},
      {"--strength 0.001", "strength"},
      {"--guidance -1", "--guidance"},
      {"--model " + (in.dir / "no_model").string(), "no_model"},
      {"--model " + broken_model.string(), "broken_model"},
      {"--trajectory nowhere", "nowhere"},
      {"--video " + (in.dir / "empty.mp4").string(), "empty.mp4"},
      {"--video " + (in.dir / "garbage.mp4").string(), "garbage.mp4"},
      {"--video " + (in.dir / "none.mp4").string(), "none.mp4"},
      {"--depth " + (in.dir / "depth5.npy").string(), "depth5.npy"},
      {"--steps many", "--steps"},
      {"--seed -4", "--seed"},
      {"--size 64xq", "--size"},
      {"--size 60x64", "multiples of 8"},
      {"--height 64", "--width"},
      {"--height 64 --width 64", "not both"},  // --size is in the base command
      {"--lora " + (in.dir / "no_lora.safetensors").string() + ":0.5", "no_lora.safetensors"},
      {"--vae-tile 30x30", "--vae-tile"},
      {"--vae-tile 40x40", "do not join"},
      {"--vae-tile 16x24", "do not join"},  // too small to plan: once an internal error of the memory plan beside it
      {"--out " + (in.dir / "a_file" / "sub").string(), "a_file"},
  };
  for (const Case& c : cases) {
    auto r = test::run_command(in.command(out, c.extra));
    EXPECT_NE(r.exit_code, 0) << c.extra;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.extra << "\n" << r.output;
    EXPECT_EQ(test::count_of(r.output, "dvs: error: "), 1u) << c.extra << "\n" << r.output;
    EXPECT_EQ(r.output.find("internal"), std::string::npos) << c.extra << "\n" << r.output;
    for (const auto& name : test::files_in(out)) ADD_FAILURE() << c.extra << " left " << name;
  }
}

// A LoRA adapter on two attention projections of the pack's transformer (inner dim 2 heads × 16), in the
// diffusers layout load_lora reads.
std::filesystem::path write_lora(const std::filesystem::path& dir) {
  return test::write_lora_adapter(dir, {"transformer_blocks.0.attn1.to_q", "transformer_blocks.1.attn1.to_v"}, 7, 0.5f);
}

TEST(PipelineCli, LoraAndVaeTilingRunsAreRecordedAndKeyTheCache) {
  PipelineInputs in;
  const std::string lora = write_lora(in.dir.path).string();
  auto record = [&](const char* out) { return nlohmann::json::parse(std::ifstream(in.dir / out / "run.json")); };

  auto tiled = test::run_command(in.command(in.dir / "tiled", "--vae-tile 48x40"));  // 64×64 frames: 2×2 overlapping tiles
  ASSERT_EQ(tiled.exit_code, 0) << tiled.output;
  EXPECT_EQ(read_video(in.dir / "tiled" / "output.mp4").shape, (Shape{9, 3, 64, 64}));
  EXPECT_TRUE(record("tiled")["settings"]["vae_tiling"].get<bool>());
  EXPECT_TRUE(record("tiled")["lora"].is_null());

  auto with_lora = test::run_command(in.command(in.dir / "lora", "--vae-tile 48x40 --lora " + lora + ":0.5"));
  ASSERT_EQ(with_lora.exit_code, 0) << with_lora.output;
  auto r = record("lora");
  EXPECT_EQ(r["lora"]["file"], lora);
  EXPECT_EQ(r["lora"]["scale"], 0.5);
  EXPECT_FALSE(r["inversion_from_cache"].get<bool>()) << "the LoRA changes the model, so the cache key";

  auto again = test::run_command(in.command(in.dir / "lora2", "--vae-tile 48x40 --lora " + lora + ":0.5 --seed 9"));
  ASSERT_EQ(again.exit_code, 0) << again.output;
  EXPECT_TRUE(record("lora2")["inversion_from_cache"].get<bool>());

  auto untiled = test::run_command(in.command(in.dir / "untiled", "--lora " + lora + ":0.5"));
  ASSERT_EQ(untiled.exit_code, 0) << untiled.output;
  EXPECT_FALSE(record("untiled")["inversion_from_cache"].get<bool>()) << "tiling changes x0, so the cache key";
  auto versions = record("untiled")["versions"];
  for (const char* k : {"dvs", "vulkan_api", "driver", "opencv"}) EXPECT_FALSE(versions[k].get<std::string>().empty()) << k;
  EXPECT_GT(record("untiled")["peak_host_bytes"].get<double>(), 0);
}

TEST(PipelineCli, HeightAndWidthAreTheSizeOption) {
  PipelineInputs in;
  std::string cmd = in.command(in.dir / "hw");
  cmd.replace(cmd.find("--size 64x64"), 12, "--height 64 --width 64");
  auto r = test::run_command(cmd);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  auto record = nlohmann::json::parse(std::ifstream(in.dir / "hw" / "run.json"));
  EXPECT_EQ(record["settings"]["height"], 64);
  EXPECT_EQ(record["settings"]["width"], 64);
}

}  // namespace
}  // namespace dvs
