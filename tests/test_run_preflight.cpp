// Preflight (dvs run/invert/batch, dvs run --check): every class of problem knowable from the options, configs,
// safetensors headers, tokenizer, LoRA and tiling is reported before any stage starts (no stage event, no
// output folder, no cache), all of them at once, with the fix. Explicit out-of-range values are errors, not the
// default. Batch files are checked whole before the first job.
#include <gtest/gtest.h>

#include <fstream>
#include <optional>
#include <vector>
#include <nlohmann/json.hpp>

#include "io/npy.hpp"
#include "io/safetensors_writer.hpp"
#include "support/files.hpp"
#include "support/model_edit.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"
#include "support/vda_pack.hpp"

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

// `dvs batch` of one job on the scene's video with `depth`, out to in.dir/a.
static test::CommandResult batch_of_one_job(const PipelineInputs& in, const std::filesystem::path& depth) {
  const auto jobs = in.dir / "jobs.jsonl";
  test::write_text(jobs, "{\"video\": \"" + in.video.string() + "\", \"depth\": \"" + depth.string() +
                             "\", \"metric-depth\": true, \"prompt\": \"a fox\", \"out\": \"" + (in.dir / "a").string() + "\"}\n");
  return test::run_command(test::program("dvs") + " batch " + jobs.string() + " --model " + in.model.string() +
                           " --frames 9 --size 64x64 --steps 4 --inversion-steps 3 --cache-dir " + in.cache.string());
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

  const auto b = batch_of_one_job(in, fewer);
  EXPECT_NE(b.exit_code, 0) << b.output;
  EXPECT_NE(b.output.find("holds 5 depth frames"), std::string::npos) << b.output;
  EXPECT_EQ(b.output.find(": running ->"), std::string::npos) << b.output;
  EXPECT_FALSE(std::filesystem::exists(in.dir / "a"));
}

// Depth of another aspect ratio than the video (its shape is in the file's header): found by run --check, render
// --check and batch's whole-file check with the render stage's own message, not after the decode (issue 34 §3).
TEST(RunPreflight, DepthOfAnotherAspectRatioIsFoundBeforeAnyWork) {
  PipelineInputs in;  // a 64x64 video
  const auto wide = in.dir / "wide.npy";
  write_npy(wide, HostTensor::from_f32({9, 64, 96}, std::vector<float>(size_t(9 * 64 * 96), 2.0f)));
  const std::string why = "wide.npy: the depth frames are 64x96 (HxW) but the video's are 64x64: another aspect ratio";
  std::string run = in.command(in.dir / "out", "--check");
  run.replace(run.find(in.depth.string()), in.depth.string().size(), wide.string());
  auto r = test::run_command(run);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(why), std::string::npos) << r.output;
  const auto fitted = test::run_command(run + " --depth-fit stretch");
  EXPECT_EQ(fitted.exit_code, 0) << "--depth-fit stretch maps it:\n" << fitted.output;

  const std::string render = test::program("dvs") + " render --video " + in.video.string() + " --depth " + wide.string() +
                             " --metric-depth --frames 9 --size 64x64 --out " + (in.dir / "r").string();
  r = test::run_command(render + " --check");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(why), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("preflight found"), std::string::npos) << r.output;

  const auto b = batch_of_one_job(in, wide);
  EXPECT_NE(b.exit_code, 0) << b.output;
  EXPECT_NE(b.output.find(why), std::string::npos) << b.output;
  EXPECT_EQ(b.output.find(": running ->"), std::string::npos) << b.output;
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

// `dvs render` and its --check meet the splat renderer's limits before any work: one frame's accumulation (4 words per
// pixel, 64 x 64 x 16 B = 64 KiB) over a forced storage binding or (at 128x128, 256 KiB) allocation, and one frame's dispatch (128 rows of workgroups at
// --size 128x128) over forced group counts, are refused by --check and by the render itself, before the output
// folder exists, naming the render and a --size; the limits just above render. A chunk is as many frames as fit
// one binding and one allocation: at a 512 KiB allocation limit 8 of the 9 frames (9 x 64 KiB would not be one
// allocation), and every chunking renders the same mask.
TEST(RenderPreflight, LimitsTheRendererMeetsAreCheckedFirst) {
  PipelineInputs in;
  const std::string render = test::program("dvs") + " render --video " + in.video.string() + " --depth " +
                             in.depth.string() + " --metric-depth --frames 9 --no-glb --quiet";
  struct Case {
    std::string limits, size, says;
    bool fits;
  };
  std::optional<std::vector<uint8_t>> first_mask;  // every chunking of the 64x64 clip renders the same
  for (const Case& c : {Case{"binding=32KiB", "64x64", "render: one 64x64 frame needs 64.00 KiB for the splat accumulation", false},
                        Case{"binding=64KiB", "64x64", "", true},
                        Case{"alloc=128KiB", "128x128", "256.00 KiB for the splat accumulation, over one allocation", false},
                        Case{"alloc=256KiB", "128x128", "", true},
                        Case{"alloc=512KiB", "64x64", "", true},  // 8 of the 9 frames per chunk
                        Case{"alloc=1GiB", "64x64", "", true},
                        Case{"groups=64", "128x128", "render: a 128x128 frame is splatted in one dispatch of 2x128 workgroups", false},
                        Case{"groups=128", "128x128", "", true}}) {
    SCOPED_TRACE(c.limits + " --size " + c.size);
    const auto out = in.dir / ("out_" + c.limits);
    const std::string cmd = "DVS_LIMITS=" + c.limits + " " + render + " --size " + c.size + " --out " + out.string();
    const auto check = test::run_command(cmd + " --check");
    const auto run = test::run_command(cmd);
    if (c.fits) {
      EXPECT_EQ(check.exit_code, 0) << check.output;
      EXPECT_EQ(run.exit_code, 0) << run.output;
      EXPECT_TRUE(std::filesystem::exists(out / "render.mp4")) << run.output;
      if (c.size == "64x64" && std::filesystem::exists(out / "mask.npy")) {
        const std::vector<uint8_t> mask = read_npy(out / "mask.npy").data;
        if (!first_mask) first_mask = mask;
        EXPECT_EQ(mask, *first_mask) << "the chunking changed the render";
      }
      continue;
    }
    EXPECT_NE(check.exit_code, 0) << check.output;
    EXPECT_NE(check.output.find(c.says), std::string::npos) << check.output;
    EXPECT_NE(check.output.find("use a smaller --size"), std::string::npos) << check.output;
    EXPECT_NE(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find(c.says), std::string::npos) << run.output;
    EXPECT_EQ(run.output.find("internal"), std::string::npos) << run.output;
    EXPECT_FALSE(std::filesystem::exists(out)) << "the render started";
  }
}

// run --depth-model: the estimate's memory is planned in run's preflight as dvs plan --depth-model plans it. With
// the allocation limit forced to 4 MiB (the model's own stages fit it untiled) the default network input (518) cannot
// allocate its window; --check and the run refuse it before any stage, naming the depth estimate and the largest
// --depth-input-size that fits, and with that size both pass and the run finishes.
TEST(RunPreflight, DepthEstimateIsPlannedBeforeAnyWork) {
  PipelineInputs in;
  const std::string run = "DVS_LIMITS=alloc=4MiB " + test::program("dvs") + " run --video " + in.video.string() +
                          " --depth-model " + test::vda_checkpoint_path().string() + " --model " + in.model.string() +
                          " --frames 9 --size 64x64 --steps 4 --inversion-steps 3 --prompt 'a red fox' --progress json" +
                          " --cache-dir " + in.cache.string();
  const auto out = in.dir / "out";
  const auto check = test::run_command(run + " --out " + out.string() + " --check");
  EXPECT_NE(check.exit_code, 0) << check.output;
  EXPECT_NE(check.output.find("the depth estimate's window input"), std::string::npos) << check.output;
  EXPECT_NE(check.output.find("exceeds maxMemoryAllocationSize 4.00 MiB"), std::string::npos) << check.output;
  const std::string key = "a smaller network input fits: --depth-input-size ";
  const size_t at = check.output.find(key);
  ASSERT_NE(at, std::string::npos) << check.output;
  const int fits = std::stoi(check.output.substr(at + key.size()));
  EXPECT_EQ(fits % 14, 0);
  EXPECT_LT(fits, 518);
  const auto refused = test::run_command(run + " --out " + out.string());
  expect_stopped_before_any_stage(in, refused, out, "--depth-input-size 518 at alloc=4MiB");
  EXPECT_NE(refused.output.find("the depth estimate's window input"), std::string::npos) << refused.output;

  const std::string smaller = run + " --depth-input-size " + std::to_string(fits) + " --out " + out.string();
  const auto passes = test::run_command(smaller + " --check");
  EXPECT_EQ(passes.exit_code, 0) << passes.output;
  const auto works = test::run_command(smaller);
  EXPECT_EQ(works.exit_code, 0) << works.output;
  EXPECT_TRUE(std::filesystem::exists(out / "output.mp4")) << works.output;
}

// --depth-model keeps its estimate in the depth cache (with --no-cache too) and renders from there: a cache folder
// that cannot be written stops run and render in their preflight, not in the depth stage after a warning that
// the run goes on uncached.
TEST(RunPreflight, AnUnwritableDepthCacheIsSaidBeforeAnyWork) {
  PipelineInputs in;
  const auto not_a_folder = in.dir / "a_file";
  test::write_text(not_a_folder, "x");
  const std::string common = " --video " + in.video.string() + " --depth-model " + test::vda_checkpoint_path().string() +
                             " --depth-input-size 28 --frames 9 --size 64x64 --cache-dir " + (not_a_folder / "cache").string();
  const auto out = in.dir / "out";
  const std::string says = "--depth-model: the estimate is kept in the depth cache, which cannot be written";
  for (const std::string& cmd : {test::program("dvs") + " run" + common + " --model " + in.model.string() +
                                     " --steps 4 --inversion-steps 3 --prompt 'a fox' --progress json --no-cache",
                                 test::program("dvs") + " render" + common + " --no-glb --progress json"}) {
    const auto check = test::run_command(cmd + " --out " + out.string() + " --check");
    EXPECT_NE(check.exit_code, 0) << check.output;
    EXPECT_NE(check.output.find(says), std::string::npos) << check.output;
    // (dvs render itself has no preflight: the estimate's own check of its cache file says it, before the work.)
    const auto r = test::run_command(cmd + " --out " + out.string());
    EXPECT_NE(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("depth cache"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("a_file is not a folder"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("not cached"), std::string::npos) << "a warning that the run goes on\n" << r.output;
    EXPECT_EQ(r.output.find("\"stage\":"), std::string::npos) << "a stage started\n" << r.output;
    EXPECT_FALSE(std::filesystem::exists(out)) << r.output;
  }
}

// A .txt trajectory whose lines hold different numbers of values is used (the authors' own loop1/loop2 files are
// like that) but never silently: a warning on stderr whatever --progress says, naming the file, each line's
// number and count and what dvs does; --check lists it too. Equal lines give no warning.
TEST(RenderPreflight, TrajectoryLinesOfDifferentLengthsAreWarnedOnStderr) {
  PipelineInputs in;
  const auto uneven = in.dir / "uneven.txt", even = in.dir / "even.txt";
  test::write_text(uneven, "0 2 10 15 12\n\n0 -3 -10\n0 -0.02 -0.09 -0.16\n");  // a blank line 2
  test::write_text(even, "0 2 10\n0 -3 -10\n0 -0.02 -0.09\n");
  const std::string render = test::program("dvs") + " render --video " + in.video.string() + " --depth " +
                             in.depth.string() + " --metric-depth --frames 9 --size 64x64 --no-glb --quiet";
  const std::string says = uneven.string() + ": its lines hold different numbers of values: line 1 (theta) 5 values, " +
                           "line 3 (phi) 3 values, line 4 (r) 4 values. dvs spreads each line over the whole clip on its own";
  // stderr alone (stdout to /dev/null).
  const auto r = test::run_command("{ " + render + " --trajectory " + uneven.string() + " --out " +
                                   (in.dir / "u").string() + " 2>&1 >/dev/null; }");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("dvs: warning: " + says), std::string::npos) << r.output;
  const auto check = test::run_command(render + " --trajectory " + uneven.string() + " --out " + (in.dir / "c").string() + " --check");
  EXPECT_EQ(check.exit_code, 0) << check.output;
  EXPECT_NE(check.output.find("warning: " + says), std::string::npos) << check.output;
  const auto quiet = test::run_command(render + " --trajectory " + even.string() + " --out " + (in.dir / "e").string());
  EXPECT_EQ(quiet.exit_code, 0) << quiet.output;
  EXPECT_EQ(quiet.output.find("warning"), std::string::npos) << quiet.output;
}

}  // namespace
}  // namespace dvs
