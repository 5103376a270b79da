// Preflight (dvs run/invert/batch, dvs run --check): every class of problem knowable from the options, configs,
// safetensors headers, tokenizer, LoRA and tiling is reported before any stage starts (no stage event, no
// output folder, no cache), all of them at once, with the fix. Explicit out-of-range values are errors, not the
// default. Batch files are checked whole before the first job.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "io/safetensors_writer.hpp"
#include "support/files.hpp"
#include "support/model_edit.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

using test::PipelineInputs;

// A LoRA for a transformer of `dim` features on block `block`'s to_q (the pack's transformer has 2 blocks of 32).
std::filesystem::path write_lora(const std::filesystem::path& file, int64_t dim, int block) {
  const int64_t r = 2;
  const std::string name = "transformer.transformer_blocks." + std::to_string(block) + ".attn1.to_q";
  write_safetensors(file, {{name + ".lora_A.weight", HostTensor::from_f32({r, dim}, std::vector<float>(size_t(r * dim), 0.1f))},
                           {name + ".lora_B.weight", HostTensor::from_f32({dim, r}, std::vector<float>(size_t(r * dim), 0.1f))}});
  return file;
}

std::string with_model(std::string cmd, const std::filesystem::path& from, const std::filesystem::path& to) {
  return cmd.replace(cmd.find(from.string()), from.string().size(), to.string());
}

// The run failed in preflight: nothing started, nothing written.
void expect_stopped_before_any_stage(const PipelineInputs& in, const test::CommandResult& r, const std::filesystem::path& out,
                                     const std::string& what) {
  EXPECT_NE(r.exit_code, 0) << what << "\n" << r.output;
  EXPECT_NE(r.output.find("preflight found"), std::string::npos) << what << "\n" << r.output;
  EXPECT_EQ(r.output.find("\"stage\":"), std::string::npos) << what << ": a stage started\n" << r.output;
  EXPECT_FALSE(std::filesystem::exists(out)) << what << ": the output folder was created";
  EXPECT_FALSE(std::filesystem::exists(in.cache)) << what << ": the cache was touched";
}

TEST(RunPreflight, EachClassOfProblemFailsBeforeAnyStage) {
  PipelineInputs in;
  const auto out = in.dir / "out";
  const auto vae_missing = test::copy_model(in.model, in.dir / "vae_missing");
  test::edit_weights(vae_missing, "vae", [](auto& t) { std::erase_if(t, [](auto& p) { return p.first == "decoder.conv_out.conv.bias"; }); });
  const auto vae_shape = test::copy_model(in.model, in.dir / "vae_shape");
  test::edit_weights(vae_shape, "vae", [](auto& t) {
    for (auto& [n, v] : t)
      if (n == "decoder.conv_out.conv.bias") v = HostTensor::from_f32({4}, std::vector<float>{0, 0, 0, 0});
  });
  const auto vae_cut = test::copy_model(in.model, in.dir / "vae_cut");
  for (const auto& e : std::filesystem::directory_iterator(vae_cut / "vae"))
    if (e.path().extension() == ".safetensors") std::filesystem::resize_file(e.path(), std::filesystem::file_size(e.path()) / 2);
  const auto no_tokenizer = test::copy_model(in.model, in.dir / "no_tokenizer");
  std::filesystem::remove(no_tokenizer / "tokenizer" / "spiece.model");
  const auto mixed = test::copy_model(in.model, in.dir / "mixed");
  test::edit_config(mixed, "transformer", [](nlohmann::json& j) { j["text_embed_dim"] = 48; });
  const auto sincos = test::copy_model(in.model, in.dir / "sincos");  // no learned table: any size, patch multiples
  test::edit_config(sincos, "transformer", [](nlohmann::json& j) { j["use_learned_positional_embeddings"] = false; });
  const auto lora_other = write_lora(in.dir / "other_model.safetensors", 64, 0).string();
  const auto lora_block = write_lora(in.dir / "block9.safetensors", 32, 9).string();

  struct Case {
    std::string extra;
    std::filesystem::path model;
    std::string expect;
  } cases[] = {
      {"--size 128x128", in.model, "this model's learned positional table needs --size 64x64"},
      {"--size 72x72", sincos, "must be multiples of 16, e.g. --size 64x64"},
      {"", vae_missing, "tensor 'decoder.conv_out.conv.bias'"},
      {"", vae_shape, "decoder.conv_out.conv.bias"},
      {"", vae_cut, "vae_cut"},
      {"", no_tokenizer, "spiece.model"},
      {"", mixed, "text_embed_dim (48)"},
      {"--lora " + lora_other, in.model, "this transformer needs A [rank, 32]"},
      {"--lora " + lora_block + ":0.5", in.model, "transformer_blocks.9.attn1.to_q"},
      {"--vae-tile 40x40", in.model, "do not join"},
      {"--frames 13", in.model, "holds 9 frames, fewer than --frames 13; use --frames 9"},
      {"--trajectory nowhere.txt", in.model, "nowhere.txt"},
      {"--depth " + (in.dir / "none.npy").string(), in.model, "none.npy: no such depth file"},
      {"--steps 2 --strength 0.4", in.model, "keeps no sampling step"},
  };
  for (const Case& c : cases) {
    auto r = test::run_command(with_model(in.command(out, c.extra), in.model, c.model));
    expect_stopped_before_any_stage(in, r, out, c.extra + " " + c.model.filename().string());
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.extra << " " << c.model.filename() << "\n" << r.output;
  }
}

TEST(RunPreflight, EveryProblemIsReportedAtOnce) {
  PipelineInputs in;
  const auto out = in.dir / "out";
  const auto lora = write_lora(in.dir / "other_model.safetensors", 64, 0).string();
  auto r = test::run_command(in.command(out, "--size 128x128 --lora " + lora + " --depth " + (in.dir / "none.npy").string()));
  expect_stopped_before_any_stage(in, r, out, "three problems");
  EXPECT_NE(r.output.find("preflight found 3 problems"), std::string::npos) << r.output;
  EXPECT_EQ(test::count_of(r.output, "\n  - "), 3u) << r.output;
  // dvs invert runs the same preflight.
  std::string invert = test::program("dvs") + " invert" + in.inputs() + " --size 128x128 --out " + out.string();
  invert.replace(invert.find("--size 64x64"), 12, "");
  r = test::run_command(invert);
  expect_stopped_before_any_stage(in, r, out, "invert");
  EXPECT_NE(r.output.find("needs --size 64x64"), std::string::npos) << r.output;
}

TEST(RunPreflight, CheckRunsNothing) {
  PipelineInputs in;
  const auto out = in.dir / "out";
  auto ok = test::run_command(in.command(out, "--check"));
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_NE(ok.output.find("preflight: no problem found"), std::string::npos) << ok.output;
  EXPECT_EQ(ok.output.find("\"stage\":"), std::string::npos) << ok.output;
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_FALSE(std::filesystem::exists(in.cache));
  auto bad = test::run_command(in.command(out, "--check --size 128x128"));
  expect_stopped_before_any_stage(in, bad, out, "--check");
}

TEST(RunPreflight, ExplicitOutOfRangeValuesAreErrorsNotTheDefault) {
  PipelineInputs in;
  const auto out = in.dir / "out";
  for (const auto& [extra, option] : std::vector<std::pair<std::string, std::string>>{
           {"--strength 0", "--strength"}, {"--strength 1.5", "--strength"}, {"--delta 0", "--delta"},
           {"--delta -2", "--delta"}, {"--k 0", "--k"}, {"--intrinsics 0,0,0,0", "--intrinsics"},
           {"--intrinsics 50,50,-1,32", "--intrinsics"}, {"--preservation-scale -1", "--preservation-scale"},
           {"--guidance -0.5", "--guidance"}, {"--preset official --delta 1.5", "--delta"},
           {"--preset official --k 2.5", "--k"}}) {
    auto r = test::run_command(in.command(out, extra + " --check"));
    EXPECT_NE(r.exit_code, 0) << extra << "\n" << r.output;
    EXPECT_NE(r.output.find(option + " must be"), std::string::npos) << extra << "\n" << r.output;
    EXPECT_FALSE(std::filesystem::exists(out)) << extra;
  }
}

// The depth file's frame count (its header) against the frames the job uses: found by run --check and by
// batch's up-front check, not in the render stage.
TEST(RunPreflight, DepthFramesAgainstFramesAreChecked) {
  PipelineInputs in;
  const auto fewer = in.dir / "depth5.npy", more = in.dir / "depth12.npy";
  PipelineInputs::write_scene_depth(fewer, 5);
  PipelineInputs::write_scene_depth(more, 12);
  auto with_depth = [&](const std::filesystem::path& depth, const std::string& extra) {
    std::string cmd = in.command(in.dir / "out", "--check " + extra);
    return test::run_command(cmd.replace(cmd.find(in.depth.string()), in.depth.string().size(), depth.string()));
  };
  auto r = with_depth(fewer, "");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("depth5.npy: holds 5 depth frames, fewer than --frames 9; give depth for every frame, or --frames 5"),
            std::string::npos) << r.output;
  r = with_depth(more, "");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("--trim-depth uses its first 9"), std::string::npos) << r.output;
  r = with_depth(more, "--trim-depth");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = with_depth(in.depth, "");
  EXPECT_EQ(r.exit_code, 0) << "the matching depth was refused:\n" << r.output;

  const auto jobs = in.dir / "jobs.jsonl";
  test::write_text(jobs, "{\"video\": \"" + in.video.string() + "\", \"depth\": \"" + fewer.string() +
                             "\", \"metric-depth\": true, \"prompt\": \"a fox\", \"out\": \"" + (in.dir / "a").string() + "\"}\n");
  auto b = test::run_command(test::program("dvs") + " batch " + jobs.string() + " --model " + in.model.string() +
                             " --frames 9 --size 64x64 --steps 4 --inversion-steps 3 --cache-dir " + in.cache.string());
  EXPECT_NE(b.exit_code, 0) << b.output;
  EXPECT_NE(b.output.find("holds 5 depth frames"), std::string::npos) << b.output;
  EXPECT_EQ(b.output.find(": running ->"), std::string::npos) << b.output;
  EXPECT_FALSE(std::filesystem::exists(in.dir / "a"));
}

TEST(BatchPreflight, TheWholeFileIsCheckedBeforeTheFirstJob) {
  PipelineInputs in;
  const std::string common = "\"video\": \"" + in.video.string() + "\", \"depth\": \"" + in.depth.string() +
                             "\", \"metric-depth\": true, \"prompt\": \"a fox\"";
  const auto jobs = in.dir / "jobs.jsonl";
  test::write_text(jobs, "{" + common + ", \"out\": \"" + (in.dir / "a").string() + "\"}\n" +            // fine
                             "{" + common + ", \"out\": \"" + (in.dir / "b").string() + "\", \"sped\": 3}\n" +  // unknown key
                             "{\"video\": \"" + in.video.string() + "\", \"out\": \"" + (in.dir / "c").string() + "\"}\n" +
                             "{" + common + ", \"out\": \"" + (in.dir / "a").string() + "/\"}\n" +  // the same out as job 0
                             "{" + common + ", \"out\": \"" + (in.dir / "e").string() + "\", \"size\": \"128x128\"}\n");
  auto r = test::run_command(test::program("dvs") + " batch " + jobs.string() + " --model " + in.model.string() +
                             " --frames 9 --size 64x64 --steps 4 --inversion-steps 3 --cache-dir " + in.cache.string());
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("4 problems found before running anything; no job was run"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("job 1 (jobs.jsonl:2): unknown key \"sped\""), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("job 2 (jobs.jsonl:3): missing required \"depth\", \"prompt\""), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("job 3 (jobs.jsonl:4): \"out\""), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("is also the out folder of job 0 (jobs.jsonl:1)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("job 4 (jobs.jsonl:5): --size 128x128: this model's learned positional table"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find(": running ->"), std::string::npos) << r.output;
  for (const char* d : {"a", "b", "c", "e"}) EXPECT_FALSE(std::filesystem::exists(in.dir / d)) << d;
}

}  // namespace
}  // namespace dvs
