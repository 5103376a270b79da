// `dvs run --weights`: a whole run with the block weights streamed gives the same output files as with them
// resident, and run.json records where they lived; --weights auto follows the memory plan for the run on the
// device it runs on, budget included (DVS_LIMITS memory=), streaming exactly the component whose phase does not
// fit. The conformance pack's model at 64x64, 9 frames: seconds per run on lavapipe.
#include <gtest/gtest.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <string>

#include "dvs/option_names.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/memory_advice.hpp"
#include "pipeline/memory_plan.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"
#include "vk/context.hpp"
#include "vk/device_limits.hpp"

namespace dvs {
namespace {

using test::PipelineInputs;

nlohmann::json run_json(const std::filesystem::path& out) {
  return nlohmann::json::parse(test::read_text(out / "run.json"));
}

TEST(WeightStreamRun, StreamedRunGivesTheResidentRunsFilesAndIsRecorded) {
  PipelineInputs in;
  auto run = [&](const std::string& weights, const std::string& out) {
    return test::run_command(test::program("dvs") + " run --quiet --no-cache" + in.inputs() +
                             " --trajectory pan_left:0.3 --prompt 'a red fox' --weights " + weights + " --out " +
                             (in.dir / out).string());
  };
  const auto resident = run("resident", "resident");
  ASSERT_EQ(resident.exit_code, 0) << resident.output;
  const auto streamed = run("stream", "streamed");
  ASSERT_EQ(streamed.exit_code, 0) << streamed.output;
  EXPECT_EQ(run_json(in.dir / "resident")["weights"],
            nlohmann::json({{"requested", "resident"}, {"transformer", "resident"}, {"text_encoder", "resident"}}));
  EXPECT_EQ(run_json(in.dir / "streamed")["weights"],
            nlohmann::json({{"requested", "stream"}, {"transformer", "stream"}, {"text_encoder", "stream"}}));
  for (const char* video : {"output.mp4", "render.mp4", "mask.mp4", "comparison.mp4"}) {
    const std::string a = test::read_text(in.dir / "resident" / video);
    ASSERT_FALSE(a.empty()) << video;
    EXPECT_TRUE(a == test::read_text(in.dir / "streamed" / video)) << video << " differs between resident and streamed";
  }
  const auto bad = run("sometimes", "bad");
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("--weights must be resident, stream or auto"), std::string::npos) << bad.output;
}

// Where the weights live changes no result, so it is not in the cache keys: a streamed run finds the sampled latent
// a resident run cached (so it loads no transformer) and gives its files.
TEST(WeightStreamRun, StreamedRunReusesTheResidentRunsCache) {
  PipelineInputs in;
  auto run = [&](const std::string& weights, const std::string& out) {
    const auto r = test::run_command(test::program("dvs") + " run --quiet" + in.inputs() +
                                     " --prompt 'a red fox' --weights " + weights + " --out " + (in.dir / out).string());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return run_json(in.dir / out);
  };
  const nlohmann::json first = run("resident", "first");
  EXPECT_FALSE(first["latent"]["reused"].get<bool>()) << first.dump();
  const nlohmann::json second = run("stream", "second");
  EXPECT_TRUE(second["latent"]["reused"].get<bool>()) << second.dump();
  EXPECT_EQ(second["latent"]["key"], first["latent"]["key"]);
  EXPECT_EQ(second["weights"], nlohmann::json({{"requested", "stream"}, {"transformer", "not loaded"},
                                               {"text_encoder", "not loaded"}}));
  EXPECT_TRUE(test::read_text(in.dir / "first" / "output.mp4") == test::read_text(in.dir / "second" / "output.mp4"));
}

TEST(WeightStreamRun, AutoStreamsTheTransformerWhenItsPhaseIsOverTheDevicesBudget) {
  PipelineInputs in;
  const RunOptions o = in.run_options(in.dir / "out", in.cache);
  ASSERT_EQ(o.weights, "auto");
  // The transformer's phase with its weights resident, from the plan's own figures (as the run plans it).
  vk::Context own;
  const pipeline::MemoryPlan open = pipeline::plan_memory(pipeline::plan_model_from_folder(o.model),
                                                          run_plan_request(o, own.caps()));
  auto bytes_of = [&](const char* name) {
    for (const auto& w : open.weights)
      if (w.name == name) return w.bytes;
    return uint64_t(0);
  };
  uint64_t call = 0;
  for (const auto& s : open.stages)
    if (s.name == "transformer_cfg" || s.name == "transformer_inversion") call = std::max(call, s.total());
  const uint64_t phase = open.carried + bytes_of("vae") + bytes_of("transformer") + call;
  ASSERT_GT(phase, 1u << 20) << "DVS_LIMITS memory= takes at least 1 MiB";
  own.override_limits(vk::parse_limit_overrides("memory=" + std::to_string(phase), "test"));
  const WeightResidencies fits = weight_residencies(own, o);
  EXPECT_EQ(fits.transformer, models::WeightResidency::resident);
  EXPECT_EQ(fits.text_encoder, models::WeightResidency::resident);
  own.override_limits(vk::parse_limit_overrides("memory=" + std::to_string(phase - 1), "test"));
  const WeightResidencies tight = weight_residencies(own, o);
  EXPECT_EQ(tight.transformer, models::WeightResidency::stream);
  EXPECT_EQ(tight.text_encoder, models::WeightResidency::resident) << "T5's phase still fits";
  // An explicit choice is obeyed whatever the budget.
  RunOptions forced = o;
  forced.weights = "resident";
  EXPECT_EQ(weight_residencies(own, forced).transformer, models::WeightResidency::resident);
  forced.weights = "stream";
  EXPECT_EQ(weight_residencies(own, forced).text_encoder, models::WeightResidency::stream);
}

// Out of device memory in the text, inversion or sampling stage with the weights resident: the advice names
// streaming (RunOptions::weights in the library, --weights in the dvs program) and what that component then
// holds; with them streamed already it does not.
TEST(WeightStreamRun, OutOfMemoryAdviceOffersStreaming) {
  PipelineInputs in;
  RunOptions o = in.run_options(in.dir / "out", in.cache);
  o.weights = "resident";
  for (const char* stage : {"text", "invert", "sample"}) {
    EXPECT_NE(out_of_memory_advice(o, stage).find("RunOptions::weights stream ("), std::string::npos) << stage;
    set_option_names(OptionNames::command_line);
    EXPECT_NE(out_of_memory_advice(o, stage).find("--weights stream ("), std::string::npos) << stage;
    set_option_names(OptionNames::fields);
  }
  EXPECT_EQ(out_of_memory_advice(o, "decode").find("weights stream"), std::string::npos);
  o.weights = "stream";
  EXPECT_EQ(out_of_memory_advice(o, "sample").find("weights stream"), std::string::npos);
}

// dvs plan's streaming figures: the bytes a call uploads over the rate given, one block's compute (batch 1, the
// inversion: 2·S·12·D² for the projections and the FFN, 4·S²·D for the attention, S = 226 + 17,550, D = 3,072)
// against its upload at the profile's peak (nvidia: 165 TFLOP/s, a transfer queue): hidden at 20 GB/s, not at 1.
TEST(WeightStreamRun, PlanTimesTheUploadsAtTheRateGiven) {
  const double S = 226 + 17550, D = 3072, flops = 2 * S * 12 * D * D + 4 * S * S * D;
  for (const double rate : {20e9, 1e9}) {
    // The profile's own figures: the limits pass's DVS_LIMITS would lower the profile below any real-size split.
    const auto r = test::run_command("env -u DVS_LIMITS " + test::program("dvs") +
                                     " plan --model cogvideox-5b-i2v --limits nvidia --budget 8GiB" +
                                     " --upload-rate " + std::to_string(int64_t(rate)) + " --json");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const nlohmann::json tr = nlohmann::json::parse(r.output)["streams"][0];
    ASSERT_EQ(tr["component"], "transformer");
    EXPECT_TRUE(tr["streamed"].get<bool>());
    EXPECT_NEAR(tr["block_flops"].get<double>(), flops, flops * 1e-12);
    EXPECT_DOUBLE_EQ(tr["call_upload_seconds"].get<double>(), tr["host_bytes"].get<double>() / rate);
    EXPECT_DOUBLE_EQ(tr["block_upload_seconds"].get<double>(), tr["slot_bytes"].get<double>() / rate);
    const bool hides = flops / 165e12 >= tr["slot_bytes"].get<double>() / rate;
    EXPECT_EQ(hides, rate > 2e9);
    EXPECT_EQ(tr["compute_longer_than_upload"].get<bool>(), hides) << tr.dump();
    EXPECT_EQ(tr["hides"].get<bool>(), hides) << tr.dump();  // the profile has a transfer queue
  }
  // amd's profile has no transfer-only queue: compute longer than the upload, but not said to hide.
  const auto amd = test::run_command("env -u DVS_LIMITS " + test::program("dvs") +
                                     " plan --model cogvideox-5b-i2v --limits amd --budget 8GiB --json");
  ASSERT_EQ(amd.exit_code, 0) << amd.output;
  const nlohmann::json a = nlohmann::json::parse(amd.output)["streams"][0];
  EXPECT_TRUE(a["compute_longer_than_upload"].get<bool>()) << a.dump();
  EXPECT_FALSE(a["hides"].get<bool>()) << a.dump();
  EXPECT_NE(a["verdict"].get<std::string>().find("without a transfer-only queue"), std::string::npos) << a.dump();
}

// dvs info --bench-upload measures the rate dvs plan --upload-rate takes.
TEST(WeightStreamRun, InfoMeasuresTheUploadRate) {
  const auto r = test::run_command(test::program("dvs") + " info --bench-upload");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const size_t at = r.output.find(" GB/s");
  ASSERT_NE(at, std::string::npos) << r.output;
  const size_t start = r.output.rfind(' ', at - 1) + 1;
  EXPECT_GT(std::stod(r.output.substr(start, at - start)), 0.0) << r.output;
  EXPECT_NE(r.output.find("dvs plan --upload-rate "), std::string::npos) << r.output;
}

}  // namespace
}  // namespace dvs
