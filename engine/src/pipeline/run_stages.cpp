// The end-to-end job's stages, once for every end (pipeline/run_stages.hpp). Every numeric stage runs on the
// device; the host plans and moves small tensors (masks' index lists, per-stage results for the outputs). Stages
// 1–5 and 9 are shared with run_inversion (pipeline/job_stages.hpp).
#include "pipeline/run_stages.hpp"

#include <vulkan/vulkan.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>

#include "diffusion/init_noise.hpp"
#include "diffusion/krnr.hpp"
#include "diffusion/sampler.hpp"
#include "diffusion/schedule.hpp"
#include "diffusion/slm.hpp"
#include "dvs/error.hpp"
#include "io/library_log.hpp"
#include "io/cache_root.hpp"
#include "io/video.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/cogvideox/vae_tiling.hpp"
#include "pipeline/cache_layout.hpp"
#include "pipeline/denoise_stages.hpp"
#include "pipeline/inversion_cache.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/latent_layout.hpp"
#include "io/option_names.hpp"
#include "pipeline/output_path.hpp"
#include "pipeline/prompt_cut.hpp"
#include "pipeline/stage_tracker.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_check.hpp"
#include "vk/context.hpp"
#include "vk/memory.hpp"

namespace dvs {

RunReport run_stages(const RunOptions& options, RunEnds& ends, vk::Context* device, StageTracker& stages) {
  RunOptions o = options;
  RunReport report;
  ends.check(o);  // every problem knowable now, before any device work
  // A cache that cannot be written is said once and the run goes on without it (caching only saves time on a
  // later run); run.json then records "cache": false and why, not the cache it could not use.
  std::string cache_problem;
  if (o.use_cache) {
    refuse_old_cache_layout(o.cache_dir);  // named, not computed again (a clip run has no preflight)
    const InversionCache cache(o.cache_dir);
    if (auto p = file_write_problem(cache.dir() / "eps_inv-write-check.npy",
                                    "point " + option_name("RunOptions::cache_dir") +
                                        " (or DVS_CACHE_DIR) at a writable folder, or turn the cache off (" +
                                        option_name("RunOptions::use_cache") + ")")) {
      cache_problem = *p;
      o.use_cache = false;
      log_warning("the cache cannot be written, so this run is not cached: " + cache_problem);
    }
  }
  JobPlan jp = plan_job(o);
  for (const std::string& w : prompt_cut_warnings(o, jp.tokenizer, jp.text_len)) log_warning(w);
  // --depth-model: the depth estimated (or cached) in a context of its own, released before the models load.
  const nlohmann::json depth_estimate = depth_stage(o, stages);
  const Settings& st = jp.settings;
  const bool dynamic_cfg = o.dynamic_cfg.value_or(st.official);  // the official code always uses it
  if (dynamic_cfg && !(o.preservation_scale >= 0 && std::isfinite(o.preservation_scale)))
    throw Error(option_name("RunOptions::preservation_scale") + " must be a finite number ≥ 0, got " +
                std::to_string(o.preservation_scale));
  const diffusion::CogVideoXSchedule& schedule = jp.schedule;
  const diffusion::SamplingPlan& plan = jp.plan;

  std::optional<vk::Context> own_device;
  if (!device) {
    vk::ContextOptions copt;
    copt.device = o.render.device;
    copt.cache_dir = o.cache_dir;  // the pipeline cache beside the run caches, as DVS_CACHE_DIR puts it
    device = &own_device.emplace(copt);
  }
  vk::Context& ctx = *device;
  // Ctrl-C and progress between the bounded submissions inside a forward or a VAE call, not only between steps.
  const vk::ScopedSegmentHook between_submissions(ctx, stages.segment_hook());

  // 1–2. Decode (or take the clip) and render.
  RenderedInput in = ends.input(ctx, o, stages);
  const int F = int(in.rgb.shape[0]);
  const std::vector<std::string> input_key = ends.input_key(o);
  const WeightResidencies residency = weight_residencies(ctx, o);  // --weights, or the plan's choice (auto)
  WeightsUsed weights_used;  // as the loaded models report it, for run.json

  // The sampled latent of an earlier run with these settings (one whose decode failed or was interrupted, or
  // one re-run with other VAE options) skips stages 3–8.
  models::CogVideoXVae vae(ctx, o.model / "vae");
  const models::VaeConfig& vcfg = vae.config();
  const int64_t r = vcfg.spatial_ratio();
  const Shape lat{(F - 1) / vcfg.temporal_compression_ratio + 1, vcfg.latent_channels, in.rgb.shape[2] / r, in.rgb.shape[3] / r};
  const float sf = float(vcfg.scaling_factor);
  const LatentCache latent_cache(o, latent_cache_key(o, jp, F, dynamic_cfg, input_key));
  std::optional<CachedLatent> cached;
  if (o.use_cache) {
    std::string rejected;
    cached = latent_cache.load(ctx, lat, &rejected);
    if (!rejected.empty()) log_warning("ignoring the cached latent " + rejected);
  }
  const int t0 = plan.t0();
  Tensor latent;  // what the decode takes: the final x0 prediction
  bool slm_fell_back = false;
  nlohmann::json latent_meta;
  if (cached) {
    stages.begin("latent", "reusing the sampled latent");
    stages.say(1, 1, "sampled latent loaded from the cache (" + latent_cache.file().string() +
                         "): encoding, inversion and sampling skipped");
    latent = cached->latent;
    latent_meta = cached->meta;
    slm_fell_back = latent_meta.value("slm_source_fell_back", false);
    stages.end();
  } else {
    // 3. VAE: the render -> x0, its first frame -> the image-conditioning latent.
    stages.begin("encode", "VAE-encoding the render");
    EncodedRender enc = encode_render(ctx, vae, o, st, in);
    const Tensor& x0 = enc.x0;
    const Tensor& image_latent = enc.image_latent;
    if (x0.shape() != lat) throw Error("internal: the encoded render is [" + shape_str(x0.shape()) + "], expected [" + shape_str(lat) + "]");
    stages.end();

    // 4. Text.
    stages.begin("text", "encoding the prompts");
    Tensor text, text_inv;
    {  // T5's weights (8.9 GiB for the real model) are freed before the transformer is loaded
      models::T5Encoder t5(ctx, o.model / "text_encoder", residency.text_encoder);
      weights_used.text_encoder = t5.residency();
      text = guidance_text(ctx, t5, jp.tokenizer, st.negative, o.prompt, jp.text_len);  // [uncond; cond]
      text_inv = t5.encode_prompts(jp.tokenizer, {""}, jp.text_len);  // inversion: "", no guidance (the official CFG
                                                                      // over two identical "" rows is a no-op)
    }
    ops::require_finite(ctx, {{&text, "prompt embeddings"}, {&text_inv, "empty-prompt embedding"}}, kNonFiniteHint);
    stages.end();

    // 5. Inversion (cached on disk).
    stages.begin("invert", "DDIM inversion");
    std::unique_ptr<models::CogVideoXTransformer> transformer_ptr = load_transformer(ctx, o, residency.transformer);
    weights_used.transformer = transformer_ptr->residency();
    models::CogVideoXTransformer& transformer = *transformer_ptr;
    InversionResult inversion = invert_render(ctx, transformer, o, jp, F, input_key, enc, text_inv, stages);
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
    ops::require_finite(ctx, {{&x_init, "x_init"}}, kNonFiniteHint);
    slm_fell_back = masks.source_fell_back;
    stages.end();

    // 8. Sampling with classifier-free guidance.
    stages.begin("sample", "guided DDIM sampling");
    {  // the transformer's weights and activations are freed before the VAE decode, the run's other large call
      ops::NonFiniteCheck check(ctx);
      diffusion::LoopCallbacks cb = stages.loop_callbacks(&check);
      diffusion::Guidance guidance{true, o.guidance};
      if (dynamic_cfg) {  // official: position-wise, P = the x0 SLM targets (V < 1)
        guidance.mode = diffusion::GuidanceMode::dynamic;
        guidance.positions = diffusion::positions_to_replace(ctx, masks, int(lat[1]));
        guidance.preservation_scale = o.preservation_scale;
      }
      diffusion::SampleResult result =
          sample_latent(ctx, transformer, schedule, plan, x_init, image_latent, text, guidance, cb, &check);
      ops::require_finite(ctx, {{&result.latent, "final latent"}, {&result.pred_x0, "final x0 prediction"}}, kNonFiniteHint);
      latent = result.pred_x0;
    }
    transformer_ptr.reset();
    // Kept before the decode, the run's other large call: nothing sampled is lost if it fails.
    const auto tiling = vae_tiling(o);
    latent_meta = {{"slm_source_fell_back", slm_fell_back},
                   {"encoded_with", {{"vae_tiling", tiling.has_value()}}},
                   {"model", o.model.string()}};
    if (tiling) {
      const auto tp = models::TilePlan::for_encode(vcfg, *tiling);
      latent_meta["encoded_with"]["vae_tile"] = {tp.tile_in_h, tp.tile_in_w};
    }
    if (o.use_cache)
      if (const std::string failed = latent_cache.store(ctx, latent, latent_meta); !failed.empty())
        log_warning("the sampled latent could not be cached (" + failed + "); a later run samples again");
    stages.end();
  }

  // 9. Decode and write.
  stages.begin("decode", "VAE-decoding the result");
  HostTensor output = decode_latent(ctx, vae, o, latent, sf, F);
  stages.end();

  ends.write(ctx, RunResults{in, output, latent}, report, stages);
  report.stages = stages.times();
  report.peak_device_bytes = ctx.allocator().stats().peak_bytes_in_use;
  const auto& caps = ctx.caps();
  RunRecordExtras extras{st.steps, st.strength, st.inversion_steps, st.delta, st.negative, t0, plan.num_steps(), caps.name,
                         caps.driver_name + " " + caps.driver_info, model_fingerprint(o.model), slm_fell_back};
  extras.vulkan_api = std::to_string(VK_API_VERSION_MAJOR(caps.api_version)) + "." +
                      std::to_string(VK_API_VERSION_MINOR(caps.api_version)) + "." +
                      std::to_string(VK_API_VERSION_PATCH(caps.api_version));
  extras.opencv = video_library_version();
  extras.depth_estimate = depth_estimate;
  extras.dynamic_cfg = dynamic_cfg;
  extras.weights = weights_used.record(o.weights);
  extras.intrinsics = {in.K.fx, in.K.fy, in.K.cx, in.K.cy};
  if (const auto tiling = vae_tiling(o)) {
    const auto tp = models::TilePlan::for_encode(vae.config(), *tiling);
    extras.vae_tile_height = int(tp.tile_in_h), extras.vae_tile_width = int(tp.tile_in_w);
  }
  std::vector<std::string> pose_text;
  for (const auto& T : in.trajectory.transforms) {
    std::array<double, 16> m{};
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m[size_t(r * 4 + c)] = T[c][r];  // glm is column-major
    extras.poses.push_back(m);
    for (double v : m) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%.17g", v);
      pose_text.push_back(buf);
    }
  }
  extras.poses_hash = InversionCache::key(pose_text);
  extras.cache_dir = o.use_cache ? cache_root(o.cache_dir).string() : "";  // what --from gives back as --cache-dir
  extras.cache_problem = cache_problem;
  if (o.use_cache) {
    extras.latent = {{"path", latent_cache.file().string()}, {"key", latent_cache.key()}, {"reused", cached.has_value()},
                     {"encoded_with", latent_meta.value("encoded_with", nlohmann::json())}};
  }
  ends.finish(o, report, extras, stages);
  return report;
}

}  // namespace dvs
