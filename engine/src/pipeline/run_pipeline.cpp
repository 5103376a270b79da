// The end-to-end job. Every numeric stage runs on the device; the host decodes and encodes video, plans,
// and moves small tensors (masks' index lists, per-stage results for the output files). Stages 1–5 and 9
// are shared with run_inversion (pipeline/job_stages.hpp).
#include <vulkan/vulkan.h>

#include <cmath>

#include "diffusion/init_noise.hpp"
#include "diffusion/krnr.hpp"
#include "diffusion/sampler.hpp"
#include "diffusion/schedule.hpp"
#include "diffusion/slm.hpp"
#include "dvs/error.hpp"
#include "dvs/pipeline.hpp"
#include "io/video.hpp"
#include "models/cogvideox_transformer.hpp"
#include "models/cogvideox_vae.hpp"
#include "models/t5_encoder.hpp"
#include "pipeline/denoise_stages.hpp"
#include "pipeline/inversion_cache.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/latent_layout.hpp"
#include "pipeline/render_stage.hpp"
#include "pipeline/run_outputs.hpp"
#include "pipeline/run_record.hpp"
#include "pipeline/stage_tracker.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"
#include "vk/memory.hpp"

namespace dvs {
namespace {

RunReport run_stages(const RunOptions& o, StageTracker& stages) {
  RunReport report;
  JobPlan jp = plan_job(o);
  const Settings& st = jp.settings;
  const bool dynamic_cfg = o.dynamic_cfg.value_or(st.official);  // the official code always uses it
  if (dynamic_cfg && !(o.preservation_scale >= 0 && std::isfinite(o.preservation_scale)))
    throw Error("--preservation-scale must be a finite number ≥ 0, got " + std::to_string(o.preservation_scale));
  const diffusion::CogVideoXSchedule& schedule = jp.schedule;
  const diffusion::SamplingPlan& plan = jp.plan;

  vk::ContextOptions copt;
  copt.device = o.render.device;
  vk::Context ctx(copt);

  // 1–2. Decode and render.
  RenderedInput in = render_for_model(ctx, o, stages);
  const int F = int(in.rgb.shape[0]);

  // 3. VAE: the render -> x0, its first frame -> the image-conditioning latent.
  stages.begin("encode", "VAE-encoding the render");
  models::CogVideoXVae vae(ctx, o.model / "vae");
  EncodedRender enc = encode_render(ctx, vae, o, st, in);
  const Tensor& x0 = enc.x0;
  const float sf = enc.scaling;
  const Tensor& image_latent = enc.image_latent;
  const Shape lat = x0.shape();  // [Fl, C, h, w]
  stages.end();

  // 4. Text.
  stages.begin("text", "encoding the prompts");
  Tensor text, text_inv;
  {  // T5's weights (8.9 GiB for the real model) are freed before the transformer is loaded
    models::T5Encoder t5(ctx, o.model / "text_encoder");
    text = guidance_text(ctx, t5, jp.tokenizer, st.negative, o.prompt, jp.text_len);  // [uncond; cond]
    text_inv = t5.encode_prompts(jp.tokenizer, {""}, jp.text_len);  // inversion: "", no guidance (the official CFG
                                                                    // over two identical "" rows is a no-op)
  }
  stages.end();

  // 5. Inversion (cached on disk).
  stages.begin("invert", "DDIM inversion");
  std::unique_ptr<models::CogVideoXTransformer> transformer_ptr = load_transformer(ctx, o);
  models::CogVideoXTransformer& transformer = *transformer_ptr;
  const int t0 = plan.t0();
  InversionResult inversion = invert_render(ctx, transformer, o, jp, F, enc, text_inv, stages);
  Tensor eps_inv = inversion.eps;
  report.inversion_from_cache = inversion.from_cache;
  stages.end();

  // 6–7. SLM and adaptive K-RNR.
  stages.begin("init_noise", "stochastic latent modulation and K-RNR");
  diffusion::SlmOptions slm;
  slm.preset = st.official ? diffusion::SlmOptions::Preset::official : diffusion::SlmOptions::Preset::paper;
  slm.seed = o.seed;
  diffusion::SlmMasks masks = diffusion::compute_slm_masks(ctx, in.mask, &in.depth, true, int(lat[0]), slm);
  diffusion::SlmPlan slm_plan = diffusion::make_slm_plan(ctx, masks, int(lat[1]), slm.scope);
  const Tensor x_init = initial_latent(ctx, st, o.k, o.seed, enc, eps_inv, &slm_plan, schedule.alpha_cumprod(t0));
  stages.end();

  // 8. Sampling with classifier-free guidance.
  stages.begin("sample", "guided DDIM sampling");
  diffusion::SampleResult result;
  {  // the transformer's weights and activations are freed before the VAE decode, the run's other large call
    diffusion::LoopCallbacks cb = stages.loop_callbacks();
    diffusion::Guidance guidance{true, o.guidance};
    if (dynamic_cfg) {  // official: position-wise, P = the x0 SLM targets (V < 1)
      guidance.mode = diffusion::GuidanceMode::dynamic;
      guidance.positions = diffusion::positions_to_replace(ctx, masks, int(lat[1]));
      guidance.preservation_scale = o.preservation_scale;
    }
    result = sample_latent(ctx, transformer, schedule, plan, x_init, image_latent, text, guidance, cb);
  }
  transformer_ptr.reset();
  stages.end();

  // 9. Decode and write.
  stages.begin("decode", "VAE-decoding the result");
  HostTensor output = decode_latent(ctx, vae, o, result.pred_x0, sf);
  stages.end();

  stages.begin("write", "writing the videos");
  RunOutputs files(o.render.out_dir);
  report.run_json = files.add("run.json");  // first: the folder stops looking finished until it is rewritten
  report.render_mp4 = files.add("render.mp4");
  report.mask_mp4 = files.add("mask.mp4");
  report.comparison_mp4 = files.add("comparison.mp4");
  report.output_mp4 = files.add("output.mp4");
  write_video(report.render_mp4, in.render, in.fps);
  write_video(report.mask_mp4, mask_as_video(in.mask), in.fps);
  write_video(report.comparison_mp4, hstack_videos({&in.rgb, &in.render, &output}), in.fps);
  write_video(report.output_mp4, output, in.fps);
  stages.end();
  stages.check_cancelled();  // the last chance before the job looks finished
  report.stages = stages.times();
  report.peak_device_bytes = ctx.allocator().stats().peak_bytes_in_use;
  const auto& caps = ctx.caps();
  RunRecordExtras extras{st.steps, st.strength, st.inversion_steps, st.delta, st.negative, t0, plan.num_steps(), caps.name,
                         caps.driver_name + " " + caps.driver_info, model_fingerprint(o.model), masks.source_fell_back};
  extras.vulkan_api = std::to_string(VK_API_VERSION_MAJOR(caps.api_version)) + "." +
                      std::to_string(VK_API_VERSION_MINOR(caps.api_version)) + "." +
                      std::to_string(VK_API_VERSION_PATCH(caps.api_version));
  extras.opencv = video_library_version();
  extras.dynamic_cfg = dynamic_cfg;
  write_run_record(report.run_json, o, report, extras);
  files.commit();
  return report;
}

}  // namespace

RunReport run_pipeline(const RunOptions& o, const ProgressFn& progress, const CancelFn& cancelled) {
  StageTracker stages(progress, cancelled);
  return stages.run([&] { return run_stages(o, stages); });
}

}  // namespace dvs
