// The pipeline end to end by value against the pack's e2e case (DVS_GOLDEN_DIR; README "End-to-end case"):
// the production stages themselves — plan_job's timesteps, encode_render, the I2V image latent, the CFG text
// rows, the transformer bound as the denoiser (TransformerDenoiser: its model-input layout and timestep), the
// inversion loop, the noise initialisation, the guided sampling loop and decode_latent — on the pack's inputs,
// comparing every step's latent and the final frames with the pack. Nothing here replays the pack's saved model
// outputs: the pack's tiny transformer runs.
//
// Two kinds of test: per stage (each stage from the pack's own inputs), and chained (everything from the video,
// the prompts' embeddings and the pack's saved generator draws, each stage fed the previous stage's result).
// Both at the pack's per-stage tolerances: the pack warns that chained errors grow, but on lavapipe the chain
// ends 7e-6 from the final latent and 5e-5 from the frames (atol 1e-4 and 1e-3).
// The pack does not cover SLM (it needs the renderer's masks), so the noise initialisation runs K-RNR only.
// Sizes, step counts, timesteps, guidance and tolerances: the pack's files and cases.json.
#include "support/pipeline_e2e.hpp"

namespace dvs {
namespace {

using namespace e2e;

TEST_F(PipelineE2e, TimestepsFromThePlan) {
  const JobPlan jp = plan_job(pack_options());
  const std::vector<float> sampling = load("e2e/sampling_timesteps.npy").to_f32();
  ASSERT_EQ(jp.plan.timesteps.size(), sampling.size());
  for (size_t i = 0; i < sampling.size(); ++i) EXPECT_EQ(jp.plan.timesteps[i], int(sampling[i])) << "sampling step " << i;
  const std::vector<float> inversion = load("e2e/inversion_timesteps.npy").to_f32();
  const auto steps = inversion_steps(jp.settings, jp.schedule, jp.plan.t0());
  ASSERT_EQ(steps.size(), inversion.size());
  for (size_t i = 0; i < inversion.size(); ++i) EXPECT_EQ(steps[i].to_t, int(inversion[i])) << "inversion step " << i;
  // The pipeline call's full schedule (strength 1).
  const auto full = jp.schedule.plan(jp.settings.steps, 1.0);
  EXPECT_EQ(full.timesteps, test::pack_case("e2e_pipeline_call").at("timesteps").get<std::vector<int>>());
}

// The CFG rows from the prompts' text: row 0 = the negative prompt (""), row 1 = the prompt ("a red fox", the
// pack's t5_text_to_embeddings case).
TEST_F(PipelineE2e, GuidanceTextRowsFromPrompts) {
  const RunOptions o = pack_options();
  const JobPlan jp = plan_job(o);
  models::T5Encoder t5(ctx(), o.model / "text_encoder");
  const std::string prompt = nlohmann::json::parse(test::read_text(test::golden_path() / "tokenizer" / "prompts.json")).at(0);
  const Tensor rows = guidance_text(ctx(), t5, jp.tokenizer, "", prompt, jp.text_len);
  ASSERT_EQ(rows.dim(0), 2);
  const auto tol = test::pack_tolerance("t5_text_to_embeddings");
  expect_close("row 0 (uncond: \"\")", rows.rows(0, 1), ctx(), "e2e/empty_embeds.npy", tol, test::kTextOps);
  expect_close("row 1 (cond: '" + prompt + "')", rows.rows(1, 1), ctx(), "t5/text_embeds.npy", tol, test::kTextOps);
}

// encode_render as `dvs run` calls it (paper preset: posterior means) on the pack's video as the render.
TEST_F(PipelineE2e, EncodeRenderLatents) {
  RunOptions o = pack_options();
  o.preset = "paper";
  const Settings st = resolve(o);
  RenderedInput in;
  in.render = frames_first(load("vae/video.npy"));
  const EncodedRender enc = encode_render(ctx(), vae(), o, st, in);
  const auto tol = test::pack_tolerance("e2e_image_latents");
  expect_close("x0 (0.7 · posterior mean)", enc.x0_mean, ctx(), "e2e/inversion_x0.npy", tol);
  expect_close("x0 = x0_mean (paper)", enc.x0, ctx(), "e2e/inversion_x0.npy", tol);
  // Image latent with the posterior mean: scaling · mean in latent frame 0, zeros after (built here from the pack).
  // (the same from PyTorch's bf16 run of the posterior mean, for the precision rule)
  const HostTensor shape_of = load("e2e/image_latents.npy");  // [1, Fl, C, h, w]
  auto latent_of = [&](const HostTensor& mean) {            // mean [1, C, 1, h, w]
    std::vector<float> want(size_t(shape_of.numel()), 0.0f);
    const std::vector<float> m = mean.to_f32();
    for (size_t i = 0; i < m.size(); ++i) want[i] = enc.scaling * m[i];
    return want;
  };
  const test::PackGolden mean = test::read_pack_golden(test::golden_path(), "e2e/image_posterior_mean.npy");
  std::optional<std::vector<float>> bf16;
  if (mean.bf16) bf16 = latent_of(*mean.bf16);
  const HostTensor ours = enc.image_latent.download(ctx());
  test::expect_golden_values("image latent (paper: posterior mean)", ours.shape, ours.to_f32(), shape_of.shape,
                             latent_of(mean.golden), bf16, mean.bf16_path.string(), tol.atol, tol.rtol,
                             test::kConvOps);
}

// The whole image latent the production code builds from the video's first frame, against the pack's.
TEST_F(PipelineE2e, ImageLatentFromTheFirstFrame) {
  const Tensor img = image_latent_of(frames_first(load("vae/video.npy")), latent_frames());
  expect_close("image_latents", img, ctx(), "e2e/image_latents.npy", test::pack_tolerance("e2e_image_latents"));
}

TEST_F(PipelineE2e, InversionStepByStep) {
  const JobPlan jp = plan_job(pack_options());
  invert_and_check(jp, pack("e2e/inversion_x0.npy"), pack("e2e/image_latents.npy"),
                   upload(load("e2e/empty_embeds.npy")));
}

// initial_latent as the official preset runs it (3 rounds, per-element AdaIN from the posterior, δ = 2), without
// SLM (the pack has no renderer masks), from the pack's x0 sample, ε_inv and posterior.
TEST_F(PipelineE2e, NoiseInitialisation) {
  const RunOptions o = pack_options();
  const JobPlan jp = plan_job(o);
  EncodedRender enc;
  enc.scaling = test::pack_scaling();
  enc.posterior.mean = upload(load("e2e/video_posterior_mean.npy"));
  enc.posterior.std = upload(load("e2e/video_posterior_std.npy"));
  enc.x0 = pack("e2e/krnr_x0.npy");
  EXPECT_EQ(diffusion::InitNoiseOptions::official().rounds, int(settings().at("krnr_rounds")));
  const Tensor x_init =
      initial_latent(ctx(), jp.settings, o.k, o.seed, enc, pack("e2e/eps_inv.npy"), nullptr, jp.schedule.alpha_cumprod(jp.plan.t0()));
  // (from the pack's inputs: elementwise arithmetic only, judged by the fp32 tolerance under every tuning)
  expect_close("x_init", x_init, ctx(), "e2e/x_init.npy", test::pack_tolerance("e2e_krnr"), test::kNoKernelOps);
}

TEST_F(PipelineE2e, SamplingStepByStepAndFrames) {
  const JobPlan jp = plan_job(pack_options());
  const diffusion::SampleResult r =
      sample_and_check(jp, jp.plan, pack("e2e/x_init.npy"), pack("e2e/image_latents.npy"), "e2e_sampling", true);
  const auto tol = test::pack_tolerance("e2e_sampling");
  expect_close("final latent", r.latent, ctx(), "e2e/final_latent.npy", tol);
  expect_close("decoded x0 prediction", r.pred_x0, ctx(), "e2e/final_latent.npy", tol);
  check_frames(r.pred_x0);
}

// CogVideoXImageToVideoPipeline.__call__ itself: all the steps from t = 999, from the pack's x_init.
TEST_F(PipelineE2e, PipelineCallLatents) {
  const JobPlan jp = plan_job(pack_options());
  const diffusion::SamplingPlan full = jp.schedule.plan(jp.settings.steps, 1.0);
  const diffusion::SampleResult r =
      sample_and_check(jp, full, pack("e2e/x_init.npy"), pack("e2e/image_latents.npy"), "e2e_pipeline_call", false);
  expect_close("pipeline_call_latents", r.latent, ctx(), "e2e/pipeline_call_latents.npy",
               test::pack_tolerance("e2e_pipeline_call"));
}

// Every stage fed the previous stage's result, from the video, the prompts' embeddings and the pack's saved
// generator draws (image and video posterior samples).
TEST_F(PipelineE2e, ChainedFromTheVideo) { chained_from_the_video(); }

}  // namespace
}  // namespace dvs
