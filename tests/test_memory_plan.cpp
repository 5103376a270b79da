// `dvs plan` and the memory planner behind it. The per-stage figures are compared with what the allocator
// really holds while each model call runs on the conformance pack's tiny model (a fresh device context per
// call, so its peak counter starts from the weights alone); the aggregation, the tiling choice and the CLI
// are checked against values computed here independently (safetensors data sizes, parameter-count formulas).
// Not repeated here: the VAE dry run vs its own working set (VaeGolden.FrameBatching17).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <random>

#include "dvs/error.hpp"
#include "spec/model_folder.hpp"
#include "io/safetensors.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/random/tiny_model.hpp"
#include "pipeline/memory_plan.hpp"
#include "support/files.hpp"
#include "support/process.hpp"
#include "vk/context.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

fs::path pack_model() { return test::golden_path() / "model"; }

json read_json(const fs::path& p) {
  std::ifstream f(p);
  return json::parse(f);
}

std::unique_ptr<vk::Context> fresh_context() {
  vk::ContextOptions o;
  o.validation = true;
  o.pipeline_cache_file = "-";
  return std::make_unique<vk::Context>(o);
}

uint64_t aligned(uint64_t bytes, uint64_t a) { return (bytes + a - 1) / a * a; }

HostTensor random_f32(const Shape& s, uint32_t seed) {
  std::mt19937 g(seed);
  std::normal_distribution<float> n(0.0f, 1.0f);
  std::vector<float> v(size_t(shape_numel(s)));
  for (float& x : v) x = n(g);
  return HostTensor::from_f32(s, v);
}

// Uploads every weight of the component, so that the peak counter afterwards measures the call alone. The VAE
// reads its convolutions' weights packed (`convs`: every tensor of rank 4 or 5, packed as the VAE does when it is made;
// packing drops the stored copy, so the peak is reset after).
void preload(models::ComponentWeights& w, vk::Context* convs = nullptr) {
  const WeightSet set = WeightSet::open_dir(w.dir());
  for (const auto& [name, ref] : set.entries()) {
    if (convs && w.info(name).shape.size() >= 4) w.packed_conv(name);
    else w.get(name);
  }
  if (convs) convs->allocator().reset_peak();
}

// Device bytes the call allocated beyond what was held before it (the allocator's peak minus that).
struct Measure {
  vk::Context& ctx;
  uint64_t before;
  explicit Measure(vk::Context& c) : ctx(c), before(c.allocator().stats().bytes_in_use) {
    EXPECT_EQ(c.allocator().stats().peak_bytes_in_use, before) << "nothing may have been freed before the call";
  }
  uint64_t delta() const { return ctx.allocator().stats().peak_bytes_in_use - before; }
};

// Data bytes of a component's safetensors files, from the file layout (8-byte length, header, data).
uint64_t data_bytes_on_disk(const fs::path& dir) {
  uint64_t total = 0;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".safetensors") {
      std::ifstream f(e.path(), std::ios::binary);
      uint64_t n = 0;
      f.read(reinterpret_cast<char*>(&n), 8);
      total += uint64_t(fs::file_size(e.path())) - 8 - n;
    }
  return total;
}

TEST(MemoryPlanLive, T5StageEqualsWhatTheCallAllocates) {
  if (!fs::exists(pack_model())) GTEST_SKIP() << "no golden pack";
  auto ctx = fresh_context();
  models::T5Encoder t5(*ctx, pack_model() / "text_encoder");
  preload(t5.weights());
  const int64_t L = read_json(pack_model() / "transformer" / "config.json").at("max_text_seq_length").get<int64_t>();
  std::vector<std::vector<int32_t>> ids(2, std::vector<int32_t>(size_t(L), 0));
  for (int64_t i = 0; i < L; ++i) ids[0][size_t(i)] = int32_t(i % 7 + 3), ids[1][size_t(i)] = int32_t(i % 5 + 1);
  Measure m(*ctx);
  const Tensor out = t5.encode(ids);
  const bool emb16 = t5.weights().get("shared.weight").dtype() != DType::f32;
  const auto plan = pipeline::plan_t5_stage(t5.weights().config(), emb16, ctx->allocator().alignment(), 2, L);
  EXPECT_EQ(plan.total(), m.delta());
  EXPECT_GT(plan.working, 0u);
}

// A d_kv that is not a multiple of 4 (6): the attention runs on head-padded copies in recording scratch,
// which the stage's figure counts (no pack needed: a generated tiny T5, batch 2, 9 tokens).
TEST(MemoryPlanLive, T5StageWithPaddedHeadsEqualsWhatTheCallAllocates) {
  test::TempDir dir;
  models::TinyModelSpec spec;
  spec.seed = 3;
  spec.t5_d_kv = 6;
  models::write_tiny_model(dir.path, spec);
  auto ctx = fresh_context();
  models::T5Encoder t5(*ctx, dir.path / "text_encoder");
  preload(t5.weights());
  const int64_t L = 9;
  std::vector<std::vector<int32_t>> ids(2, std::vector<int32_t>(size_t(L), 0));
  for (int64_t i = 0; i < L; ++i) ids[0][size_t(i)] = int32_t(i % 7 + 3), ids[1][size_t(i)] = int32_t(i % 5 + 1);
  Measure m(*ctx);
  const Tensor out = t5.encode(ids);
  const auto plan = pipeline::plan_t5_stage(t5.weights().config(), false, ctx->allocator().alignment(), 2, L);
  EXPECT_EQ(plan.total(), m.delta());
  const auto unpadded = [&] {
    json cfg = t5.weights().config();
    cfg["d_kv"] = 8;
    return pipeline::plan_t5_stage(cfg, false, ctx->allocator().alignment(), 2, L);
  }();
  EXPECT_GT(plan.io, unpadded.io) << "the padded copies are counted";
}

TEST(MemoryPlanLive, TransformerStagesEqualWhatTheCallsAllocate) {
  if (!fs::exists(pack_model())) GTEST_SKIP() << "no golden pack";
  const json cfg = read_json(pack_model() / "transformer" / "config.json");
  const int64_t F = (cfg.at("sample_frames").get<int64_t>() - 1) / 4 + 1, H = cfg.at("sample_height").get<int64_t>(),
                W = cfg.at("sample_width").get<int64_t>(), L = cfg.at("max_text_seq_length").get<int64_t>();
  for (int64_t B : {int64_t(2), int64_t(1)}) {
    auto ctx = fresh_context();
    const uint64_t a = ctx->allocator().alignment();
    models::CogVideoXTransformer tr(*ctx, pack_model() / "transformer");
    preload(tr.weights());
    const Shape lat{B, F, cfg.at("in_channels").get<int64_t>(), H, W}, txt{B, L, cfg.at("text_embed_dim").get<int64_t>()};
    const Tensor latent = Tensor::upload(*ctx, random_f32(lat, 1)), text = Tensor::upload(*ctx, random_f32(txt, 2));
    Measure m(*ctx);
    const float t = 500.0f;
    const Tensor out = tr.forward(latent, text, std::span<const float>(&t, 1));
    // The plan counts the call's inputs too; the test uploaded them before measuring.
    const uint64_t inputs = aligned(uint64_t(shape_numel(lat)) * 4, a) + aligned(uint64_t(shape_numel(txt)) * 4, a);
    // Under the limits in force: where attention splits (DVS_LIMITS), its scratch is in the plan too.
    const auto plan = pipeline::plan_transformer_stage(cfg, a, B, F, H, W, L, 2, &ctx->caps());
    EXPECT_EQ(plan.total(), m.delta() + inputs) << "batch " << B;
  }
}

// The VAE's dry run counts each pool buffer unpadded; the allocator pads the few small ones (GroupNorm scratch)
// to its alignment. So the live peak may exceed the plan by a few alignments, never fall below it.
void expect_vae_plan(uint64_t plan, uint64_t measured, uint64_t alignment) {
  EXPECT_GE(measured, plan);
  EXPECT_LE(measured, plan + 4 * alignment) << "plan " << plan << ", measured " << measured;
}

TEST(MemoryPlanLive, VaeStagesEqualWhatTheCallsAllocate) {
  if (!fs::exists(pack_model())) GTEST_SKIP() << "no golden pack";
  const json cfg = read_json(pack_model() / "vae" / "config.json");
  const Shape video{1, 3, 9, 64, 64}, z{1, cfg.at("latent_channels").get<int64_t>(), 3, 8, 8};
  {
    auto ctx = fresh_context();
    models::CogVideoXVae vae(*ctx, pack_model() / "vae");
    preload(vae.weights(), ctx.get());
    const Tensor in = Tensor::upload(*ctx, random_f32(video, 3));
    Measure m(*ctx);
    const auto post = vae.encode(in);
    const auto plan = pipeline::plan_vae_encode_stage(cfg, ctx->allocator().alignment(), video);
    expect_vae_plan(plan.total(), m.delta() + aligned(uint64_t(shape_numel(video)) * 4, ctx->allocator().alignment()),
                    ctx->allocator().alignment());
  }
  {
    auto ctx = fresh_context();
    models::CogVideoXVae vae(*ctx, pack_model() / "vae");
    preload(vae.weights(), ctx.get());
    const Tensor in = Tensor::upload(*ctx, random_f32(z, 4));
    Measure m(*ctx);
    const Tensor frames = vae.decode(in);
    const auto plan = pipeline::plan_vae_decode_stage(cfg, ctx->allocator().alignment(), z);
    expect_vae_plan(plan.total(), m.delta() + aligned(uint64_t(shape_numel(z)) * 4, ctx->allocator().alignment()),
                    ctx->allocator().alignment());
  }
  {  // Two frame batches (9 + 8 frames): the plan is an upper figure there, never below the real peak.
    const Shape v17{1, 3, 17, 32, 32};
    auto ctx = fresh_context();
    models::CogVideoXVae vae(*ctx, pack_model() / "vae");
    preload(vae.weights(), ctx.get());
    const Tensor in = Tensor::upload(*ctx, random_f32(v17, 5));
    Measure m(*ctx);
    const auto post = vae.encode(in);
    const uint64_t measured = m.delta() + aligned(uint64_t(shape_numel(v17)) * 4, ctx->allocator().alignment());
    const auto plan = pipeline::plan_vae_encode_stage(cfg, ctx->allocator().alignment(), v17);
    EXPECT_GE(plan.total(), measured);
    EXPECT_LE(plan.total(), measured + plan.io) << "over by more than the I/O allowance";
  }
}

// The whole-run aggregation and the weights of the pack, from independent sources.
TEST(MemoryPlan, AggregatesThePackModel) {
  if (!fs::exists(pack_model())) GTEST_SKIP() << "no golden pack";
  pipeline::PlanRequest req;
  req.frames = 9;
  req.height = 64;
  req.width = 64;
  req.alignment = 64;
  auto plan = pipeline::plan_memory(pipeline::plan_model_from_folder(pack_model()), req);
  ASSERT_EQ(plan.weights.size(), 3u);
  uint64_t total = 0;
  for (const auto& w : plan.weights) {
    EXPECT_TRUE(w.from_headers) << w.name;
    EXPECT_EQ(w.bytes, data_bytes_on_disk(pack_model() / w.name)) << w.name;
    total += w.bytes;
  }
  EXPECT_EQ(plan.weights_total, total);
  EXPECT_EQ(plan.latent_frames, 3);
  EXPECT_EQ(plan.latent_height, 8);
  EXPECT_EQ(plan.latent_width, 8);
  ASSERT_EQ(plan.stages.size(), 6u);
  // The render first (its buffers freed before the VAE loads), then the model calls in the order below.
  ASSERT_EQ(plan.stages[0].name, "render");
  const pipeline::StageMemory render = plan.stages[0];
  plan.stages.erase(plan.stages.begin());
  // Phases as the pipeline runs them: the VAE resident throughout, T5 for the text stage only, the transformer
  // for inversion and sampling only.
  auto w = [&](const char* name) {
    for (const auto& c : plan.weights)
      if (c.name == name) return c.bytes;
    ADD_FAILURE() << name;
    return uint64_t(0);
  };
  const uint64_t phases[] = {w("vae") + w("text_encoder") + plan.stages[0].total(),
                             w("vae") + w("transformer") + std::max(plan.stages[1].total(), plan.stages[2].total()),
                             w("vae") + plan.stages[3].total(), w("vae") + plan.stages[4].total()};
  EXPECT_EQ(plan.run_peak, std::max(render.total(), plan.carried + *std::max_element(std::begin(phases), std::end(phases))));
  EXPECT_LT(plan.run_peak, plan.weights_total + plan.carried + plan.stages[4].total());
  // Carried: embeddings [2 + 1, 8, 32] f32 and four latents [3, 4, 8, 8] f32 (all multiples of 64 bytes).
  EXPECT_EQ(plan.carried, uint64_t(3 * 8 * 32 * 4 + 4 * 3 * 4 * 8 * 8 * 4));
  // The CFG call of batch 2 needs more than the inversion call of batch 1.
  EXPECT_GT(plan.stages[1].total(), plan.stages[2].total());
  EXPECT_EQ(plan.tilings[0].run_peak, plan.run_peak);
}

TEST(MemoryPlan, ChoosesUntiledThenTheLargestTileThatFitsThenNothing) {
  const auto model = pipeline::builtin_plan_model("cogvideox-5b-i2v");
  pipeline::PlanRequest req;
  const auto open = pipeline::plan_memory(model, req);
  ASSERT_GE(open.tilings.size(), 3u);
  EXPECT_EQ(open.chosen, -1) << "no budget, no choice";
  // Smaller tiles never need more.
  for (size_t i = 1; i < open.tilings.size(); ++i) {
    EXPECT_TRUE(open.tilings[i].tiled);
    EXPECT_LE(open.tilings[i].vae_decode.total(), open.tilings[i - 1].vae_decode.total());
    EXPECT_LE(open.tilings[i].run_peak, open.tilings[i - 1].run_peak);
  }
  // The default tile is diffusers' (half the VAE's sample size: 240 x 360) and its TilePlan is the VAE's.
  const auto& first = open.tilings[1];
  EXPECT_EQ(first.tiling.tile_sample_min_height, 240);
  EXPECT_EQ(first.tiling.tile_sample_min_width, 360);
  const auto vcfg = models::VaeConfig::from_json(model.vae);
  EXPECT_EQ(first.decode.tile_in_h, models::TilePlan::for_decode(vcfg, first.tiling).tile_in_h);
  EXPECT_EQ(first.decode.tile_in_w, 45);  // 360 / 8
  // Tiles per frame for 480 x 720 with strides 200 x 288: ceil(480/200) x ceil(720/288) = 3 x 3.
  EXPECT_EQ(first.tiles, 9);

  req.budget = open.tilings[0].run_peak;  // exactly the untiled peak
  EXPECT_EQ(pipeline::plan_memory(model, req).chosen, 0);
  req.budget = open.tilings[0].run_peak - 1;
  const auto tight = pipeline::plan_memory(model, req);
  ASSERT_GE(tight.chosen, 1);
  EXPECT_LE(tight.tilings[size_t(tight.chosen)].run_peak, *req.budget);
  for (int i = 0; i < tight.chosen; ++i) EXPECT_GT(tight.tilings[size_t(i)].run_peak, *req.budget) << i;
  req.budget = 2ull << 30;  // less than the streamed transformer's phase (its slots, the VAE and one call)
  const auto none = pipeline::plan_memory(model, req);
  EXPECT_EQ(none.chosen, -1);
  ASSERT_FALSE(none.notes.empty());
  EXPECT_NE(none.notes.back().find("nothing fits"), std::string::npos) << none.notes.back();
  EXPECT_NE(none.notes.back().find("transformer weights streamed"), std::string::npos) << none.notes.back();
}

// --weights auto streams a component only where its phase does not fit with its weights resident; resident and
// stream are obeyed; the streamed phase counts the slots and the component's other weights, not its blocks.
TEST(MemoryPlan, WeightsAutoStreamsOnlyWhatDoesNotFit) {
  const auto model = pipeline::builtin_plan_model("cogvideox-5b-i2v");
  auto residency = [&](const pipeline::MemoryPlan& p, const char* c) {
    return pipeline::planned_residency(p, c) == models::WeightResidency::stream ? "stream" : "resident";
  };
  pipeline::PlanRequest req;
  req.budget = 80ull << 30;
  const auto roomy = pipeline::plan_memory(model, req);
  EXPECT_STREQ(residency(roomy, "transformer"), "resident");
  EXPECT_STREQ(residency(roomy, "text_encoder"), "resident");
  // 12 GiB: T5's phase (VAE 0.4 + T5 8.9 GiB + its call) fits, the transformer's (0.4 + 10.5 + 2.1 GiB) does not.
  req.budget = 12ull << 30;
  const auto mid = pipeline::plan_memory(model, req);
  EXPECT_STREQ(residency(mid, "transformer"), "stream");
  EXPECT_STREQ(residency(mid, "text_encoder"), "resident");
  ASSERT_GE(mid.chosen, 0);
  // The streamed transformer: 42 blocks of the same size, 2 slots of one block each, the rest resident; the host
  // copy and the bytes one call uploads are every block. Each block: 4 projections of D x D + biases, the FFN
  // (D x 4D twice + biases), two adaLN tables T x 6D + biases and four norm vectors pairs, bf16, each tensor
  // 256-byte aligned.
  const pipeline::WeightStreamPlan& tr = mid.streams.at(0);
  ASSERT_EQ(tr.component, "transformer");
  EXPECT_EQ(tr.blocks, 42);
  const uint64_t D = 3072, T = 512, Dh = 64;
  auto al = [](uint64_t b) { return (b + 255) / 256 * 256; };
  const uint64_t block = 4 * (al(D * D * 2) + al(D * 2)) + al(4 * D * D * 2) + al(4 * D * 2) + al(4 * D * D * 2) +
                         al(D * 2) + 2 * (al(6 * D * T * 2) + al(6 * D * 2)) + 4 * al(D * 2) /* norm1/2 w, b */ +
                         4 * al(Dh * 2) /* norm_q/k w, b */;
  EXPECT_EQ(tr.slot_bytes, block);
  EXPECT_EQ(tr.host_bytes, 42 * block);
  EXPECT_EQ(tr.device_bytes(), tr.resident_bytes + 2 * block);
  EXPECT_LT(tr.resident_bytes, 200ull << 20);  // embeddings, positional table, output projection
  req.weights = pipeline::WeightsChoice::resident;
  EXPECT_EQ(pipeline::plan_memory(model, req).chosen, -1) << "12 GiB does not hold the resident transformer's phase";
  req.weights = pipeline::WeightsChoice::stream;
  const auto forced = pipeline::plan_memory(model, req);
  EXPECT_STREQ(residency(forced, "text_encoder"), "stream");
  EXPECT_LT(forced.tilings[size_t(forced.chosen)].run_peak, 12ull << 30);
}

TEST(MemoryPlan, ParsesSizesAndRejectsBadOnes) {
  EXPECT_EQ(pipeline::parse_byte_size("24GiB"), 24ull << 30);
  EXPECT_EQ(pipeline::parse_byte_size("80GB"), 80000000000ull);
  EXPECT_EQ(pipeline::parse_byte_size("1.5 GiB"), 3ull << 29);
  EXPECT_EQ(pipeline::parse_byte_size("512mib"), 512ull << 20);
  EXPECT_EQ(pipeline::parse_byte_size("1000"), 1000ull);
  for (const char* bad : {"", "GiB", "24XB", "-3GiB", "1.2.3GiB", "0"}) EXPECT_THROW(pipeline::parse_byte_size(bad), Error) << bad;
}

// Parameter counts of the real CogVideoX-5B-I2V written out from the module definitions (independent of the
// schema code): D = 48 x 64, 42 blocks, time_embed 512, text 4096, in 32, out 16, patch 2, 49 x 60 x 90 sample.
uint64_t real_transformer_params() {
  const uint64_t D = 48 * 64, T = 512, blocks = 42, tokens = 226 + 13 * 30 * 45;
  const uint64_t block = 2 * (T * 6 * D + 6 * D + 2 * D)      // norm1, norm2: linear + LayerNorm
                         + 2 * 2 * 64                            // q/k per-head LayerNorm
                         + 4 * (D * D + D)                       // to_q, to_k, to_v, to_out.0
                         + (D * 4 * D + 4 * D) + (4 * D * D + D);  // ff
  return (32 * 2 * 2 * D + D) + (4096 * D + D) + tokens * D  // patch conv, text proj, learned positions
         + (D * T + T) + (T * T + T)                          // time embedding MLP
         + blocks * block + 2 * D + (T * 2 * D + 2 * D) + 2 * D + (D * 2 * 2 * 16 + 2 * 2 * 16);
}

// T5-XXL v1.1 encoder: shared embedding, 24 blocks of attention (q, k, v, o) + gated FFN + 2 RMSNorms, the
// relative bias table in block 0, the final norm.
uint64_t real_t5_params() {
  const uint64_t d = 4096, inner = 64 * 64, ff = 10240;
  return 32128 * d + 24 * (4 * d * inner + 3 * d * ff + 2 * d) + 32 * 64 + d;
}

test::CommandResult dvs_plan(const std::string& args) { return test::run_command(test::program("dvs") + " plan " + args); }

TEST(MemoryPlanCli, RealConfigWithoutAFolder) {
  const auto r = dvs_plan("--model cogvideox-5b-i2v --budget 80GiB --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json j = json::parse(r.output);
  std::map<std::string, uint64_t> bytes;
  for (const auto& w : j["weights"]) bytes[w["name"]] = w["bytes"].get<uint64_t>();
  EXPECT_EQ(bytes["transformer"], 2 * real_transformer_params());
  EXPECT_NEAR(double(real_transformer_params()), 5.6e9, 0.1e9);
  EXPECT_EQ(bytes["text_encoder"], 2 * real_t5_params());
  EXPECT_GT(bytes["vae"], 2 * 150'000'000ull);  // the CogVideoX VAE has ~215M parameters
  EXPECT_LT(bytes["vae"], 2 * 300'000'000ull);
  EXPECT_EQ(j["latent"], json({13, 60, 90}));
  // The CFG call's activations at least hold its [2, 226 + 17550, 3072] f32 sequence twice.
  const double seq = 2.0 * (226 + 17550) * 3072 * 4;
  for (const auto& s : j["stages"])
    if (s["name"] == "transformer_cfg") EXPECT_GT(s["working_bytes"].get<double>(), 2 * seq);
  EXPECT_TRUE(j["choice"]["fits"].get<bool>());
  EXPECT_FALSE(j["choice"]["tiled"].get<bool>()) << "80 GiB holds the untiled run";

  const auto tight = dvs_plan("--model cogvideox-5b-i2v --budget 24GiB --json");
  ASSERT_EQ(tight.exit_code, 0) << tight.output;
  const json t = json::parse(tight.output);
  EXPECT_TRUE(t["choice"]["fits"].get<bool>());
  EXPECT_TRUE(t["choice"]["tiled"].get<bool>()) << "the untiled VAE decode does not fit beside 20 GB of weights";

  // 8 GiB: both components stream (their resident phases are 13 and 9.4 GiB), the VAE runs in tiles.
  const auto eight = dvs_plan("--model cogvideox-5b-i2v --budget 8GiB --json");
  ASSERT_EQ(eight.exit_code, 0) << eight.output;
  const json e = json::parse(eight.output);
  EXPECT_TRUE(e["choice"]["fits"].get<bool>());
  EXPECT_EQ(e["weights_residency"], json({{"text_encoder", "stream"}, {"transformer", "stream"}}));
  const auto table = dvs_plan("--model cogvideox-5b-i2v --budget 2GiB");
  EXPECT_EQ(table.exit_code, 1) << "nothing fits: exit 1 (README)\n" << table.output;
  EXPECT_NE(table.output.find("NOTHING FITS"), std::string::npos) << table.output;
  EXPECT_NE(table.output.find("transformer_cfg"), std::string::npos) << table.output;
}

TEST(MemoryPlanCli, PackFolder) {
  if (!fs::exists(pack_model())) GTEST_SKIP() << "no golden pack";
  const auto r = dvs_plan("--model '" + pack_model().string() + "' --frames 9 --height 64 --width 64 --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const json j = json::parse(r.output);
  uint64_t total = 0;
  for (const auto& w : j["weights"]) {
    EXPECT_EQ(w["bytes"].get<uint64_t>(), data_bytes_on_disk(pack_model() / w["name"].get<std::string>())) << w["name"];
    total += w["bytes"].get<uint64_t>();
  }
  EXPECT_EQ(j["weights_total_bytes"].get<uint64_t>(), total);
  EXPECT_GT(j["run_peak_bytes"].get<uint64_t>(), total);
  const auto human = dvs_plan("--model '" + pack_model().string() + "' --frames 9 --height 64 --width 64");
  EXPECT_EQ(human.exit_code, 0) << human.output;
  EXPECT_NE(human.output.find("vae_decode"), std::string::npos) << human.output;
}

TEST(MemoryPlanCli, BadInputIsAClearError) {
  test::TempDir dir;
  struct Case {
    std::string args, expect;
  };
  fs::create_directories(dir / "m" / "transformer");
  test::write_text(dir / "m" / "transformer" / "config.json", "{}");
  const std::vector<Case> cases = {
      {"--model cogvideox-5b-i2v --frames 10", "4k+1"},
      {"--model cogvideox-5b-i2v --budget 24XB", "--budget"},
      {"--model cogvideox-5b-i2v --budget lots", "--budget"},
      {"--model cogvideox-5b-i2v --height 470", "multiples of 16"},
      {"--model '" + (dir / "nope").string() + "'", "no such model folder"},
      {"--model '" + (dir / "m").string() + "'", "vae/config.json"},
      {"--frames 9", "--model"},
      {"--model cogvideox-5b-i2v --colour red", "--colour"},
  };
  for (const auto& c : cases) {
    const auto r = dvs_plan(c.args);
    EXPECT_NE(r.exit_code, 0) << c.args;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << "\n" << r.output;
  }
}

}  // namespace
}  // namespace dvs
