// No lost work: `dvs run` keeps the sampled latent in the cache before the VAE decode, so a run interrupted
// (or failing) in the decode is re-run with other VAE options straight to the decode, and gives the frames
// an uninterrupted run gives. Driven in-process on the conformance pack's tiny model (9 frames of 64x64).
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>

#include "dvs/cache.hpp"
#include "dvs/error.hpp"
#include "dvs/logs.hpp"
#include "dvs/pipeline.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "pipeline/cache_entry.hpp"
#include "pipeline/job_stages.hpp"
#include "support/pipeline_inputs.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The options PipelineInputs::command gives on the command line.
RunOptions options(const test::PipelineInputs& in, const fs::path& cache, const fs::path& out) {
  return in.run_options(out, cache);
}

struct RunResult {
  std::set<std::string> stages;  // every stage that reported progress
  RunReport report;
  json record;
};

// Runs the pipeline; `cancel_in` names a stage during which an interrupt (Ctrl-C) arrives.
RunResult run(const RunOptions& o, const std::string& cancel_in = "") {
  RunResult r;
  bool interrupt = false;
  auto progress = [&](const std::string& stage, int, int, const std::string&) {
    r.stages.insert(stage);
    if (stage == cancel_in) interrupt = true;
  };
  r.report = run_pipeline(o, progress, [&] { return interrupt; });
  r.record = json::parse(std::ifstream(r.report.run_json));
  return r;
}

std::string bytes_of(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST(LatentCache, InterruptedDecodeIsReRunStraightToTheDecode) {
  test::PipelineInputs in;
  // The uninterrupted run.
  const RunResult first = run(options(in, in.dir / "cache1", in.dir / "out1"));
  ASSERT_TRUE(first.record["latent"].is_object()) << first.record.dump(2);
  EXPECT_FALSE(first.record["latent"]["reused"].get<bool>());
  const fs::path latent1 = first.record["latent"]["path"].get<std::string>();
  ASSERT_TRUE(fs::exists(latent1));

  // The same run in another cache, interrupted while it decodes: no outputs, but the latent is kept.
  RunOptions o = options(in, in.dir / "cache2", in.dir / "out2");
  bool cancelled = false;
  try {
    run(o, "decode");
  } catch (const Cancelled&) {
    cancelled = true;
  }
  ASSERT_TRUE(cancelled) << "the interrupt was not seen";
  EXPECT_FALSE(fs::exists(in.dir / "out2" / "output.mp4"));
  EXPECT_FALSE(fs::exists(in.dir / "out2" / "run.json"));
  const fs::path latent2 = cache_folder(in.dir / "cache2") / latent1.filename();
  ASSERT_TRUE(fs::exists(latent2)) << "the sampled latent was not cached before the decode";
  EXPECT_EQ(bytes_of(latent2), bytes_of(latent1)) << "the interrupted run sampled another latent";

  // Re-run with other VAE options: straight to the decode (no encode, text, inversion, noise or sampling).
  RunOptions tiled = o;
  tiled.vae_tiling = true;
  tiled.vae_tile_height = 48;
  tiled.vae_tile_width = 40;
  tiled.render.out_dir = in.dir / "out3";
  const RunResult again = run(tiled);
  for (const char* skipped : {"encode", "text", "invert", "init_noise", "sample"}) {
    EXPECT_FALSE(again.stages.count(skipped)) << skipped << " ran";
    EXPECT_FALSE(again.record["seconds"].contains(skipped)) << skipped;
  }
  EXPECT_TRUE(again.stages.count("latent"));
  EXPECT_TRUE(again.stages.count("decode"));
  EXPECT_TRUE(again.record["latent"]["reused"].get<bool>());
  EXPECT_EQ(again.record["latent"]["path"].get<std::string>(), latent2.string());
  EXPECT_FALSE(again.record["latent"]["encoded_with"]["vae_tiling"].get<bool>()) << "the latent was encoded untiled";
  EXPECT_TRUE(again.record["settings"]["vae_tiling"].get<bool>());
  EXPECT_EQ(read_video(again.report.output_mp4).shape, (Shape{9, 3, 64, 64}));

  // And with the first run's VAE options: the uninterrupted run's frames, exactly.
  o.render.out_dir = in.dir / "out4";
  const RunResult same = run(o);
  EXPECT_TRUE(same.record["latent"]["reused"].get<bool>());
  EXPECT_FALSE(same.stages.count("sample"));
  const HostTensor a = read_video(first.report.output_mp4), b = read_video(same.report.output_mp4);
  ASSERT_EQ(a.shape, b.shape);
  EXPECT_EQ(a.data, b.data) << "the re-run's frames differ from the uninterrupted run's";
}

TEST(LatentCache, FailedDecodeKeepsTheLatent) {
  test::PipelineInputs in;
  RunOptions o = options(in, in.dir / "cache", in.dir / "out");
  // The decode fails as it starts (as an out-of-memory error would).
  auto fail_at_decode = [](const std::string& stage, int, int, const std::string&) {
    if (stage == "decode") throw Error("decode stage: out of device memory (injected)");
  };
  EXPECT_THROW(run_pipeline(o, fail_at_decode), Error);
  EXPECT_FALSE(fs::exists(in.dir / "out" / "output.mp4"));
  int latents = 0;
  for (const auto& e : fs::directory_iterator(cache_folder(in.dir / "cache")))
    latents += e.path().filename().string().rfind("latent-", 0) == 0 && e.path().extension() == ".npy";
  EXPECT_EQ(latents, 1) << "the sampled latent was not kept";
  o.vae_tiling = true;
  const RunResult again = run(o);
  EXPECT_TRUE(again.record["latent"]["reused"].get<bool>());
  EXPECT_FALSE(again.stages.count("sample"));
  EXPECT_FALSE(again.stages.count("invert"));
}

TEST(LatentCache, ADamagedLatentIsSampledAgain) {
  test::PipelineInputs in;
  RunOptions o = options(in, in.dir / "cache", in.dir / "out1");
  const RunResult first = run(o);
  const fs::path file = first.record["latent"]["path"].get<std::string>();
  HostTensor latent = read_npy(file);
  latent.as<float>()[3] = std::numeric_limits<float>::infinity();
  write_cache_entry(file, latent);  // a whole entry (its marker matches) that holds an Inf
  o.render.out_dir = in.dir / "out2";
  std::vector<std::string> warnings;  // a warning goes to the log handler (dvs/logs.hpp), not into the progress
  set_log_handler([&](LogLevel, const std::string& message) { warnings.push_back(message); });
  RunReport report = run_pipeline(o);
  set_log_handler({});
  const json record = json::parse(std::ifstream(report.run_json));
  EXPECT_FALSE(record["latent"]["reused"].get<bool>());
  EXPECT_TRUE(record["seconds"].contains("sample"));
  bool said = false;
  for (const auto& w : warnings) said |= w.find("ignoring the cached latent") != std::string::npos;
  EXPECT_TRUE(said);
  const HostTensor again = read_npy(file);  // sampled and stored again: finite
  for (int64_t i = 0; i < again.numel(); ++i) ASSERT_TRUE(std::isfinite(again.as<float>()[i])) << i;
}

TEST(LatentCache, KeyHasWhatDeterminesTheLatentAndNotTheVaeOptions) {
  test::PipelineInputs in;
  const RunOptions base = options(in, in.dir / "cache", in.dir / "out");
  auto key = [&](const RunOptions& o) { return latent_cache_key(o, plan_job(o), 9, false); };
  const std::string k = key(base);
  // VAE options, the device, the output folder and the cache folder do not change the latent's key.
  for (auto change : std::vector<std::function<void(RunOptions&)>>{
           [](RunOptions& o) { o.vae_tiling = true; },
           [](RunOptions& o) { o.vae_tiling = true, o.vae_tile_height = 48, o.vae_tile_width = 40; },
           [](RunOptions& o) { o.render.device = "llvmpipe"; },
           [](RunOptions& o) { o.render.out_dir = "/elsewhere"; }}) {
    RunOptions o = base;
    change(o);
    EXPECT_EQ(key(o), k);
  }
  // Everything that determines the latent does.
  int n = 0;
  for (auto change : std::vector<std::function<void(RunOptions&)>>{
           [](RunOptions& o) { o.seed = 7; }, [](RunOptions& o) { o.prompt = "a blue fox"; },
           [](RunOptions& o) { o.negative_prompt = "blurry"; }, [](RunOptions& o) { o.guidance = 3; },
           [](RunOptions& o) { o.k = 3; }, [](RunOptions& o) { o.steps = 5; }, [](RunOptions& o) { o.strength = 0.9; },
           [](RunOptions& o) { o.inversion_steps = 2; }, [](RunOptions& o) { o.delta = 1.5; },
           [](RunOptions& o) { o.preset = "official"; }, [](RunOptions& o) { o.render.trajectory = "pan_left"; },
           [](RunOptions& o) { o.render.hard_points = true; }, [](RunOptions& o) { o.render.fx = o.render.fy = 40, o.render.cx = o.render.cy = 32; },
           [](RunOptions& o) { o.render.depth_fit = "stretch"; }}) {
    RunOptions o = base;
    change(o);
    EXPECT_NE(key(o), k) << "change " << n;
    ++n;
  }
  EXPECT_NE(latent_cache_key(base, plan_job(base), 9, true), k) << "dynamic CFG";
}

}  // namespace
}  // namespace dvs
