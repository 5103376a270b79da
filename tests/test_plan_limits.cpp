// `dvs plan` against device limits (--limits PROFILE, --device N): each stage's largest tensor, the verdicts,
// the recommendation, exit codes, and that every tile size it offers is one `dvs run` accepts.
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>

#include "dvs/error.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/memory_plan.hpp"
#include "support/process.hpp"
#include "vk/limit_profiles.hpp"

namespace dvs {
namespace {

using nlohmann::json;

// DVS_LIMITS cleared unless the test sets it: the tiny-limits profile must not change the real-size plans.
test::CommandResult plan(const std::string& args, const std::string& env = "DVS_LIMITS=") {
  return test::run_command(env + " " + test::program("dvs") + " plan --model cogvideox-5b-i2v " + args);
}

// run's acceptance of --vae-tile HxW: settings' multiples of 8 and check_tiles_join.
void expect_run_accepts(const models::VaeConfig& cfg, int64_t h, int64_t w) {
  EXPECT_TRUE(h > 0 && w > 0 && h % 8 == 0 && w % 8 == 0) << h << "x" << w;
  models::VaeTiling t;
  t.tile_sample_min_height = int(h);
  t.tile_sample_min_width = int(w);
  EXPECT_NO_THROW(check_tiles_join(cfg, t)) << h << "x" << w;
}

TEST(PlanLimits, EveryOfferedTileIsOneRunAccepts) {
  auto vae = pipeline::builtin_plan_model("cogvideox-5b-i2v").vae;
  // The real config, and odd sample sizes where halving lands on sizes whose tiles do not join (120 x 176 did).
  for (auto [sh, sw] : {std::pair{480, 720}, std::pair{232, 344}, std::pair{184, 312}}) {
    vae["sample_height"] = sh, vae["sample_width"] = sw;
    const auto cfg = models::VaeConfig::from_json(vae);
    const auto sizes = pipeline::plan_tile_sizes(cfg);
    ASSERT_FALSE(sizes.empty()) << sh << "x" << sw;
    for (const auto& [h, w] : sizes) expect_run_accepts(cfg, h, w);
  }
  // What the CLI prints, too.
  const auto r = plan("--json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto cfg = models::VaeConfig::from_json(pipeline::builtin_plan_model("cogvideox-5b-i2v").vae);
  int tiled = 0;
  const json printed = json::parse(r.output);
  for (const auto& t : printed["tilings"])
    if (t["tiled"].get<bool>()) {
      ++tiled;
      expect_run_accepts(cfg, t["tile_sample_min_height"].get<int64_t>(), t["tile_sample_min_width"].get<int64_t>());
    }
  EXPECT_GE(tiled, 2);
}

TEST(PlanLimits, ProfilesAreWellFormed) {
  for (const auto& p : vk::limit_profiles()) {
    EXPECT_GE(p.binding, 1u << 27) << p.name << ": below the spec's maxStorageBufferRange minimum";
    EXPECT_GE(p.texels, 65536u) << p.name;
    EXPECT_GE(p.alloc, 1u << 30) << p.name;
    EXPECT_GE(p.groups[0], 65535u) << p.name;
    EXPECT_GT(p.heap, 0u) << p.name;
    EXPECT_FALSE(p.source.empty()) << p.name;
  }
  const auto& min = vk::limit_profile("MIN");
  EXPECT_EQ(min.binding, 1u << 27);
  EXPECT_EQ(min.texels, 65536u);
  EXPECT_EQ(min.alloc, 1u << 30);
  EXPECT_THROW(vk::limit_profile("voodoo"), Error);
}

TEST(PlanLimits, NvidiaAt24GiBRecommendsTheDefaultTile) {
  const auto r = plan("--limits nvidia --budget 24GiB --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json j = json::parse(r.output);
  EXPECT_EQ(j["limits"]["binding_bytes"].get<uint64_t>(), 0xFFFFFFFFull);
  ASSERT_TRUE(j["choice"]["fits"].get<bool>());
  EXPECT_TRUE(j["choice"]["tiled"].get<bool>());
  EXPECT_EQ(j["choice"]["tile_sample_min_height"], 240);
  EXPECT_EQ(j["choice"]["tile_sample_min_width"], 360);
  // The CFG call's largest tensors are its [2, 17776, 3072] f32 sequence (and its norm, K and V): one 4 GiB
  // binding, one texel view of 2^27 (the FFN state, [2, 2222, 12288] per token chunk, is half that).
  for (const auto& s : j["stages"])
    if (s["name"] == "transformer_cfg") {
      EXPECT_EQ(s["limits"]["largest_tensor_bytes"].get<uint64_t>(), 2ull * 17776 * 3072 * 4);
      EXPECT_EQ(s["limits"]["bindings"], 1);
      EXPECT_EQ(s["limits"]["texel_views"], 1);
      EXPECT_TRUE(s["limits"]["allocation_fits"].get<bool>());
    }
  EXPECT_EQ(j["weights_residency"], json({{"text_encoder", "resident"}, {"transformer", "resident"}}))
      << "24 GiB holds both resident";
  // The table says which tile to pass to dvs run.
  const auto table = plan("--limits nvidia --budget 24GiB");
  EXPECT_EQ(table.exit_code, 0) << table.output;
  EXPECT_NE(table.output.find("dvs run --vae-tile 240x360"), std::string::npos) << table.output;
  EXPECT_NE(table.output.find("split into"), std::string::npos) << table.output;
}

TEST(PlanLimits, AllocationLimitForcesTiling) {
  // lavapipe: 2 GiB allocations: the untiled decode's largest activation is over it, the transformer's is not.
  const auto r = plan("--limits lavapipe --budget 64GiB --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json j = json::parse(r.output);
  EXPECT_TRUE(j["choice"]["tiled"].get<bool>());
  const json& untiled = j["tilings"][0];
  EXPECT_FALSE(untiled["runs"].get<bool>());
  EXPECT_NE(untiled["blocker"].get<std::string>().find("maxMemoryAllocationSize"), std::string::npos) << untiled.dump();
  EXPECT_LE(untiled["run_peak_bytes"].get<uint64_t>(), 64ull << 30) << "refused for the allocation, not the budget";
  // 128 MiB bindings: the CFG call's sequence [2, 17776, 3072] f32 takes 4 of them.
  for (const auto& s : j["stages"])
    if (s["name"] == "transformer_cfg") EXPECT_EQ(s["limits"]["bindings"], (2ull * 17776 * 3072 * 4 + (128 << 20) - 1) / (128 << 20));
}

// Issue 33's goal: every profile runs the real model (49 x 480 x 720) at 8 GiB, and at 6 GiB with both components
// streamed; no tensor of the chosen setting, no stream slot, is over the profile's allocation limit (1 GiB on the
// minimum profile). The figures come from dvs plan --json, checked against the limits it prints.
TEST(PlanLimits, EveryProfileRunsTheRealModelAtEightAndSixGiB) {
  for (const char* profile : {"lavapipe", "nvidia", "amd", "intel", "apple", "min"})
    for (const char* budget : {"8GiB", "6GiB"}) {
      const auto r = plan(std::string("--limits ") + profile + " --budget " + budget + " --json");
      ASSERT_EQ(r.exit_code, 0) << profile << " " << budget << "\n" << r.output;
      const json j = json::parse(r.output);
      const std::string at = std::string(profile) + " at " + budget;
      ASSERT_TRUE(j["choice"]["fits"].get<bool>()) << at;
      const uint64_t alloc = j["limits"]["alloc_bytes"].get<uint64_t>(), peak = j["choice"]["run_peak_bytes"];
      EXPECT_LE(peak, pipeline::parse_byte_size(budget, "test")) << at;
      if (std::string(budget) == "6GiB")
        EXPECT_EQ(j["weights_residency"], json({{"text_encoder", "stream"}, {"transformer", "stream"}})) << at;
      uint64_t largest = 0;
      for (const auto& s : j["stages"])
        if (s.contains("limits") && s["name"] != "vae_encode" && s["name"] != "vae_decode")
          largest = std::max(largest, s["limits"]["largest_tensor_bytes"].get<uint64_t>());
      for (const auto& t : j["tilings"])
        if (t["tile_sample_min_height"] == j["choice"]["tile_sample_min_height"] &&
            t["tile_sample_min_width"] == j["choice"]["tile_sample_min_width"] && t["tiled"] == j["choice"]["tiled"])
          for (const char* call : {"vae_encode", "vae_decode"})
            largest = std::max(largest, t[call]["limits"]["largest_tensor_bytes"].get<uint64_t>());
      for (const auto& st : j["streams"])
        if (st["streamed"].get<bool>()) largest = std::max(largest, st["slot_bytes"].get<uint64_t>());
      EXPECT_GT(largest, 100u << 20) << at << ": the VAE's tile activations are hundreds of MiB";
      EXPECT_LE(largest, alloc) << at;
      if (std::string(profile) == "min") EXPECT_LE(largest, 1ull << 30) << at;
    }
}

TEST(PlanLimits, MinimumLimitsRunAtEightAndSixGiBStreamedButTinyBudgetsRefuse) {
  // The Vulkan minimums (1 GiB allocations, 128 MiB bindings) and their assumed 8 GiB: both components streamed,
  // every tensor within one allocation, the VAE in tiles; at 6 GiB too, with smaller tiles.
  for (const char* budget : {"", " --budget 6GiB"}) {
    const auto r = plan(std::string("--limits min --json") + budget);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const json j = json::parse(r.output);
    EXPECT_TRUE(j["choice"]["fits"].get<bool>());
    EXPECT_TRUE(j["choice"]["tiled"].get<bool>());
    EXPECT_EQ(j["weights_residency"], json({{"text_encoder", "stream"}, {"transformer", "stream"}}));
    for (const auto& s : j["stages"])  // the untiled VAE calls are over it; the chosen tiles are not (choice)
      if (s.contains("limits") && s["name"] != "vae_encode" && s["name"] != "vae_decode")
        EXPECT_TRUE(s["limits"]["allocation_fits"].get<bool>()) << s.dump();
    // The plan says what streaming costs: the bytes uploaded per call and their time at the profile's rate.
    for (const auto& st : j["streams"]) {
      EXPECT_GT(st["uploaded_bytes_per_call"].get<uint64_t>(), 8ull << 30) << st.dump();
      EXPECT_GT(st["call_upload_seconds"].get<double>(), 0.5) << st.dump();
      EXPECT_FALSE(st["verdict"].get<std::string>().empty());
    }
  }
  // Resident weights do not fit the minimum profile's 8 GiB.
  const auto resident = plan("--limits min --weights resident");
  EXPECT_EQ(resident.exit_code, 1) << resident.output;
  EXPECT_NE(resident.output.find("NOTHING FITS"), std::string::npos) << resident.output;
  const auto tiny = plan("--limits nvidia --budget 2GiB");
  EXPECT_EQ(tiny.exit_code, 1) << tiny.output;
  EXPECT_NE(tiny.output.find("NOTHING FITS"), std::string::npos) << tiny.output;
  EXPECT_EQ(plan("--limits voodoo").exit_code, 2);
  EXPECT_EQ(plan("--limits nvidia --device 0").exit_code, 2);
}

TEST(PlanLimits, DeviceLimitsHonourDvsLimits) {
  const auto r = plan("--device 0 --budget 64GiB --json", "DVS_LIMITS=alloc=256MiB");
  EXPECT_EQ(r.exit_code, 1) << r.output;  // the CFG call's sequence [2, 17776, 3072] f32 (417 MiB) is one tensor
  const json j = json::parse(r.output);
  EXPECT_EQ(j["limits"]["alloc_bytes"].get<uint64_t>(), 256ull << 20);
  const auto open = plan("--device 0 --budget 64GiB --json");
  ASSERT_EQ(open.exit_code, 0) << open.output;
  EXPECT_GT(json::parse(open.output)["limits"]["alloc_bytes"].get<uint64_t>(), 1ull << 30);
  // A profile is lowered the same way.
  const auto lowered = plan("--limits nvidia --budget 24GiB --json", "DVS_LIMITS=alloc=256MiB");
  EXPECT_EQ(lowered.exit_code, 1) << lowered.output;
  EXPECT_EQ(json::parse(lowered.output)["limits"]["alloc_bytes"].get<uint64_t>(), 256ull << 20);
}

// Limits so small that attention finds no split: a verdict of the plan (exit 1, the stage says why), never an
// internal error (exit 3) or a bare exception (before: "internal: attention: no split of heads …").
TEST(PlanLimits, LimitsNoSplitFitsAreAVerdict) {
  const auto r = plan("--device 0 --json", "DVS_LIMITS=binding=4KiB,texels=1024,alloc=64KiB");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(r.output.find("internal"), std::string::npos) << r.output;
  const json j = json::parse(r.output);
  int cannot = 0;
  for (const auto& s : j["stages"])
    if (s["name"] == "t5_encode" || s["name"] == "transformer_cfg" || s["name"] == "transformer_inversion") {
      EXPECT_NE(s["what"].get<std::string>().find("attention does not fit this device's limits"), std::string::npos) << s.dump();
      ++cannot;
    }
  EXPECT_EQ(cannot, 3) << r.output;
  EXPECT_FALSE(j["choice"]["fits"].get<bool>()) << j["choice"].dump();
}

}  // namespace
}  // namespace dvs
