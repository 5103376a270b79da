// The inversion and depth cache keys, input by input: every input that changes the cached result must change
// the key (a hit there would reuse a wrong result), and every input the result does not read must leave it
// (a miss there would repeat minutes of work). The keys are computed directly, without a device; one run
// through the program checks that the pipeline uses them (InversionCacheKey.RunHitsAndMissesAsTheKeySays).
#include <gtest/gtest.h>

#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>

#include "dvs/depth_estimate.hpp"
#include "pipeline/depth_source.hpp"
#include "pipeline/job_stages.hpp"
#include "support/files.hpp"
#include "support/lora_adapter.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"
#include "support/vda_pack.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
using Change = std::function<void(RunOptions&)>;

struct Named {
  const char* name;
  Change change;
};

std::string inversion_key(const RunOptions& o) { return inversion_cache_key(o, plan_job(o), o.render.frames); }

fs::path write_adapter(const fs::path& dir, uint32_t seed) {
  std::filesystem::create_directories(dir);
  return test::write_lora_adapter(dir, {"transformer_blocks.0.attn1.to_q"}, seed, 1.0f);
}

TEST(InversionCacheKey, ChangesWithEveryInputOfTheInversionAndNothingElse) {
  test::PipelineInputs in;
  const RunOptions base = in.run_options(in.dir / "out", in.dir / "cache");
  const std::string k = inversion_key(base);
  // Another video and depth of the same size, another model (one config byte differs), two adapters.
  const fs::path video2 = in.dir / "scene2.mp4", depth2 = in.dir / "depth2.npy", model2 = in.dir / "model2";
  {
    HostTensor frames({9, 3, 64, 64}, DType::f32);
    for (int64_t i = 0; i < frames.numel(); ++i) frames.as<float>()[i] = float(i % 97) / 48.0f - 1.0f;
    write_video(video2, frames, 10.0);
    HostTensor depth = read_npy(in.depth);
    for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] *= 1.5f;
    write_npy(depth2, depth);
    fs::copy(in.model, model2, fs::copy_options::recursive);
    auto cfg = nlohmann::json::parse(std::ifstream(model2 / "transformer" / "config.json"));
    cfg["dvs_test_marker"] = 1;  // a changed config is a changed model
    std::ofstream(model2 / "transformer" / "config.json") << cfg.dump(1);
  }
  const fs::path lora_a = write_adapter(in.dir / "a", 3), lora_b = write_adapter(in.dir / "b", 4);
  const std::vector<Named> misses = {
      {"video", [&](RunOptions& o) { o.render.video = video2; }},
      {"depth", [&](RunOptions& o) { o.render.depth = depth2; }},
      {"depth as disparity", [](RunOptions& o) { o.render.metric_depth = false; }},
      {"model (weights/config)", [&](RunOptions& o) { o.model = model2; }},
      {"frames", [](RunOptions& o) { o.render.frames = 5; }},
      {"size", [](RunOptions& o) { o.render.height = 48; }},
      {"resize", [](RunOptions& o) { o.render.squash = true; }},
      {"trajectory", [](RunOptions& o) { o.render.trajectory = "pan_left"; }},
      {"points", [](RunOptions& o) { o.render.hard_points = true; }},
      {"intrinsics", [](RunOptions& o) { o.render.fx = o.render.fy = 40, o.render.cx = o.render.cy = 32; }},
      {"depth fit", [](RunOptions& o) { o.render.depth_fit = "stretch"; }},
      {"trim depth", [](RunOptions& o) { o.render.trim_depth = true; }},
      {"steps", [](RunOptions& o) { o.steps = 8; }},  // t0 = steps · strength
      {"strength", [](RunOptions& o) { o.strength = 0.5; }},
      {"inversion steps", [](RunOptions& o) { o.inversion_steps = 2; }},
      {"preset", [](RunOptions& o) { o.preset = "official"; }},
      {"lora", [&](RunOptions& o) { o.lora = lora_a; }},
      {"vae tiling", [](RunOptions& o) { o.vae_tiling = true; }},
      {"vae tile size", [](RunOptions& o) { o.vae_tiling = true, o.vae_tile_height = 48, o.vae_tile_width = 40; }},
  };
  for (const auto& m : misses) {
    RunOptions o = base;
    m.change(o);
    EXPECT_NE(inversion_key(o), k) << m.name << " changes ε_inv but not the key";
  }
  // The LoRA's file and its scale (any difference in the scale, not only in six decimals).
  RunOptions la = base, lb = base, ls = base;
  la.lora = lb.lora = ls.lora = lora_a;
  lb.lora = lora_b;
  ls.lora_scale = 1.0 + 1e-9;
  EXPECT_NE(inversion_key(la), inversion_key(lb)) << "another adapter file";
  EXPECT_NE(inversion_key(la), inversion_key(ls)) << "another LoRA scale";
  // The official preset encodes the first frame as a posterior sample drawn with the seed: the image latent the
  // inversion reads depends on it there (not under paper, which takes the posterior mean).
  RunOptions official = base, official_seed = base;
  official.preset = official_seed.preset = "official";
  official_seed.seed = 7;
  EXPECT_NE(inversion_key(official), inversion_key(official_seed)) << "official preset: the seed draws the image latent";

  // What the inversion does not read: the prompts, guidance, k, delta, the seed under paper, the device, the folders.
  const std::vector<Named> hits = {
      {"prompt", [](RunOptions& o) { o.prompt = "a blue fox"; }},
      {"negative prompt", [](RunOptions& o) { o.negative_prompt = "blurry"; }},
      {"guidance", [](RunOptions& o) { o.guidance = 3; }},
      {"dynamic cfg", [](RunOptions& o) { o.dynamic_cfg = true, o.preservation_scale = 0.5; }},
      {"k", [](RunOptions& o) { o.k = 3; }},
      {"delta", [](RunOptions& o) { o.delta = 1.5; }},
      {"seed (paper)", [](RunOptions& o) { o.seed = 7; }},
      {"device", [](RunOptions& o) { o.render.device = "llvmpipe"; }},
      {"out", [](RunOptions& o) { o.render.out_dir = "/elsewhere"; }},
      {"cache dir", [](RunOptions& o) { o.cache_dir = "/elsewhere"; }},
      {"intrinsics typed out as the default", [](RunOptions& o) {
         const geometry::Intrinsics K = job_intrinsics(o.render);
         o.render.fx = K.fx, o.render.fy = K.fy, o.render.cx = K.cx, o.render.cy = K.cy;
       }},
  };
  for (const auto& h : hits) {
    RunOptions o = base;
    h.change(o);
    EXPECT_EQ(inversion_key(o), k) << h.name << " does not change ε_inv but changes the key";
  }
}

TEST(DepthCacheKey, ChangesWithEveryInputOfTheEstimateAndNothingElse) {
  test::PipelineInputs in;
  DepthJob base;
  base.video = in.video;
  base.model = test::vda_golden_path() / "model" / "video_depth_anything_tiny.pth";
  base.input_size = 28;
  base.frames = 9;
  const std::string k = depth_cache_key(base);
  const fs::path video2 = in.dir / "scene2.mp4", model2 = in.dir / "other.pth";
  {
    HostTensor frames({9, 3, 64, 64}, DType::f32);
    for (int64_t i = 0; i < frames.numel(); ++i) frames.as<float>()[i] = float(i % 89) / 44.0f - 1.0f;
    write_video(video2, frames, 10.0);
    std::string bytes = test::read_text(base.model);
    bytes[bytes.size() / 2] ^= 1;  // one weight byte
    test::write_text(model2, bytes);
  }
  const std::vector<std::pair<const char*, std::function<void(DepthJob&)>>> misses = {
      {"video", [&](DepthJob& d) { d.video = video2; }},
      {"model", [&](DepthJob& d) { d.model = model2; }},
      {"input size", [](DepthJob& d) { d.input_size = 42; }},
      {"frames", [](DepthJob& d) { d.frames = 5; }},
      {"max res", [](DepthJob& d) { d.max_res = 32; }},
      {"metric", [](DepthJob& d) { d.metric = true; }},
  };
  for (const auto& [name, change] : misses) {
    DepthJob d = base;
    change(d);
    EXPECT_NE(depth_cache_key(d), k) << name << " changes the estimate but not the key";
  }
  const std::vector<std::pair<const char*, std::function<void(DepthJob&)>>> hits = {
      {"device", [](DepthJob& d) { d.device = "llvmpipe"; }},
      {"cache dir", [](DepthJob& d) { d.cache_dir = "/elsewhere"; }},
      {"refresh", [](DepthJob& d) { d.refresh_cache = true; }},
      {"option name", [](DepthJob& d) { d.input_size_option = "--depth-input-size"; }},
      {"forecast", [](DepthJob& d) { d.forecast_after_s = 1; }},
  };
  for (const auto& [name, change] : hits) {
    DepthJob d = base;
    change(d);
    EXPECT_EQ(depth_cache_key(d), k) << name << " does not change the estimate but changes the key";
  }
}

// Through the program: a run with another prompt, guidance and seed takes ε_inv from the cache; one with another
// --trim-depth (the key missed it) computes it again.
TEST(InversionCacheKey, RunHitsAndMissesAsTheKeySays) {
  test::PipelineInputs in;
  auto from_cache = [&](const std::string& name, const std::string& extra) {
    const auto r = test::run_command(in.command(in.dir / name, extra));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return nlohmann::json::parse(std::ifstream(in.dir / name / "run.json"))["inversion_from_cache"].get<bool>();
  };
  EXPECT_FALSE(from_cache("first", ""));
  EXPECT_TRUE(from_cache("hit", "--seed 9 --guidance 2 --negative-prompt blurry --prompt 'a cat'"));
  EXPECT_FALSE(from_cache("miss", "--trim-depth"));
}

}  // namespace
}  // namespace dvs
