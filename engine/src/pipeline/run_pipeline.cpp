// The end-to-end job. Every numeric stage runs on the device; the host decodes and encodes video, plans,
// and moves small tensors (masks' index lists, per-stage results for the output files).
#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>

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
#include "models/tokenizer.hpp"
#include "pipeline/inversion_cache.hpp"
#include "pipeline/render_stage.hpp"
#include "pipeline/run_record.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_layout.hpp"
#include "tensor/ops_random.hpp"
#include "vk/context.hpp"
#include "vk/memory.hpp"

namespace dvs {
namespace {

using Clock = std::chrono::steady_clock;

// The official code's fixed negative prompt (reference/official-code.md §5.1).
constexpr const char* kOfficialNegativePrompt =
    "The video is not of a high quality, it has a low resolution. Watermark present in each frame. The background "
    "is solid. Strange body and strange trajectory. Distortion. ";

struct Settings {
  bool official = false;
  int steps = 50, inversion_steps = 30;
  double strength = 0.95, delta = 3;
  std::string negative;
};

Settings resolve(const RunOptions& o) {
  if (o.preset != "paper" && o.preset != "official")
    throw Error("--preset must be paper or official, got '" + o.preset + "'");
  Settings s;
  s.official = o.preset == "official";
  s.steps = o.steps > 0 ? o.steps : (s.official ? 30 : 50);
  s.strength = o.strength > 0 ? o.strength : (s.official ? 0.98 : 0.95);
  s.inversion_steps = o.inversion_steps > 0 ? o.inversion_steps : 30;
  s.delta = o.delta > 0 ? o.delta : (s.official ? 2 : 3);
  s.negative = !o.negative_prompt.empty() ? o.negative_prompt : (s.official ? kOfficialNegativePrompt : "");
  if (!(s.strength > 0 && s.strength <= 1)) throw Error("--strength must be in (0, 1], got " + std::to_string(s.strength));
  if (!(o.k > 0)) throw Error("--k must be > 0");
  if (!(o.guidance >= 0)) throw Error("--guidance must be ≥ 0");
  if (s.steps > 1000 || s.inversion_steps > 1000) throw Error("--steps and --inversion-steps must be ≤ 1000");
  return s;
}

// [F,C,H,W] (diffusion layout) <-> [1,C,F,H,W] (VAE layout) on the device.
Tensor to_vae_layout(vk::Context& ctx, const Tensor& latent, float scale) {
  const Shape& s = latent.shape();
  Tensor scaled = Tensor::empty(ctx, s, DType::f32, "latent"), out = Tensor::empty(ctx, {1, s[1], s[0], s[2], s[3]}, DType::f32, "VAE latent");
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    ops::scale(rec, latent, scaled, scale);
    ops::permute(rec, scaled, out.reshape({s[1], s[0], s[2], s[3]}), {1, 0, 2, 3});
  });
  return out;
}

Tensor to_diffusion_layout(vk::Context& ctx, const Tensor& vae_latent, float scale) {
  const Shape& s = vae_latent.shape();  // [1, C, F, H, W]
  Tensor perm = Tensor::empty(ctx, {s[2], s[1], s[3], s[4]}, DType::f32, "latent"), out = Tensor::empty(ctx, perm.shape(), DType::f32, "latent");
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    ops::permute(rec, vae_latent.reshape({s[1], s[2], s[3], s[4]}), perm, {1, 0, 2, 3});
    ops::scale(rec, perm, out, scale);
  });
  return out;
}

// Video [F,3,H,W] on the host -> [1,3,F,H,W] on the device.
Tensor video_to_device(vk::Context& ctx, const HostTensor& frames) {
  const Shape& s = frames.shape;
  Tensor in = Tensor::upload(ctx, frames), out = Tensor::empty(ctx, {1, s[1], s[0], s[2], s[3]}, DType::f32, "video");
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::permute(rec, in, out.reshape({s[1], s[0], s[2], s[3]}), {1, 0, 2, 3}); });
  return out;
}

HostTensor video_to_host(vk::Context& ctx, const Tensor& video) {
  const Shape& s = video.shape();  // [1,3,F,H,W]
  Tensor out = Tensor::empty(ctx, {s[2], s[1], s[3], s[4]}, DType::f32, "video");
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::permute(rec, video.reshape({s[1], s[2], s[3], s[4]}), out, {1, 0, 2, 3}); });
  return out.download(ctx);
}

// x = mean + std·N(0,1) with Philox noise (the official preset's posterior samples).
Tensor posterior_sample(vk::Context& ctx, const models::VaePosterior& p, uint64_t seed, uint32_t stream) {
  Tensor noise = Tensor::empty(ctx, p.mean.shape(), DType::f32, "noise"), out = Tensor::empty(ctx, p.mean.shape(), DType::f32, "sample");
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    ops::random_normal(rec, noise, {seed, stream, 0});
    models::CogVideoXVae::sample(rec, p, noise, out);
  });
  return out;
}

// The transformer as a diffusion::Denoiser: input = concat(x, image latent) on channels for each CFG row.
class TransformerDenoiser {
 public:
  TransformerDenoiser(vk::Context& ctx, models::CogVideoXTransformer& model, const Tensor& image_latent, const Tensor& text,
                      int batch)
      : ctx_(ctx), model_(model), image_(image_latent), text_(text), batch_(batch) {
    const Shape& s = image_latent.shape();  // [F, C, H, W]
    input_ = Tensor::empty(ctx, {batch, s[0], 2 * s[1], s[2], s[3]}, DType::f32, "transformer input");
    timesteps_ = Tensor::empty(ctx, {batch}, DType::f32, "timesteps");
    model.rope_tables(s[0], s[2], s[3]);
    model.positional_embedding(s[0], s[2], s[3], text.dim(1));
    arena_ = std::make_unique<vk::Arena>(ctx.allocator(), model.arena_bytes(batch, s[0], s[2], s[3], text.dim(1)),
                                         "transformer activations");
  }
  void operator()(vk::Recorder& rec, const Tensor& x, int t, const Tensor& v) {
    const Shape& s = image_.shape();
    std::vector<float> ts(static_cast<size_t>(batch_), static_cast<float>(t));
    timesteps_.write(ctx_, HostTensor::from_f32({batch_}, ts));  // host write before this recording runs
    Tensor row0 = input_.rows(0, 1);
    ops::concat(rec, {x.reshape({1, s[0], s[1], s[2], s[3]}), image_.reshape({1, s[0], s[1], s[2], s[3]})}, row0, 2);
    for (int b = 1; b < batch_; ++b) rec.copy(row0.buffer(), input_.rows(b, 1).buffer(), row0.bytes());
    arena_->reset();
    model_.record(rec, *arena_, input_, text_, timesteps_, v);
  }

 private:
  vk::Context& ctx_;
  models::CogVideoXTransformer& model_;
  Tensor image_, text_, input_, timesteps_;
  int batch_;
  std::unique_ptr<vk::Arena> arena_;
};

}  // namespace

RunReport run_pipeline(const RunOptions& o, const ProgressFn& progress) {
  auto say = [&](const std::string& stage, int step, int total, const std::string& note) {
    if (progress) progress(stage, step, total, note);
  };
  RunReport report;
  auto stage_start = Clock::now();
  auto end_stage = [&](const std::string& name) {
    report.stages.push_back({name, std::chrono::duration<double>(Clock::now() - stage_start).count()});
    stage_start = Clock::now();
  };
  const Settings st = resolve(o);
  if (o.render.frames != 0 && (o.render.frames - 1) % 4 != 0)
    throw Error("--frames must be 4k+1 (1, 5, 9, …, 49): the VAE compresses time by 4 after the first frame");
  if (!std::filesystem::is_directory(o.model))
    throw Error(o.model.string() + ": no such model folder (give --model DIR laid out like THUDM/CogVideoX-5b-I2V)");
  // Cheap checks of the model before any long work.
  diffusion::CogVideoXSchedule schedule(diffusion::load_scheduler_config(o.model));
  diffusion::SamplingPlan plan = schedule.plan(st.steps, st.strength);
  T5Tokenizer tokenizer = T5Tokenizer::load(o.model);
  const int text_len = max_text_seq_length(o.model);

  vk::ContextOptions copt;
  copt.device = o.render.device;
  vk::Context ctx(copt);

  // 1–2. Decode and render.
  say("render", 0, 0, "decoding and rendering");
  RenderedInput in = render_stage(ctx, o.render, [&](const std::string& s) { say("render", 0, 0, s); });
  const int F = int(in.rgb.shape[0]);
  if ((F - 1) % 4 != 0)
    throw Error(o.render.video.string() + ": " + std::to_string(F) + " frames were decoded; the model needs 4k+1 — pass --frames");
  end_stage("render");

  // 3. VAE: the render -> x0, its first frame -> the image-conditioning latent.
  say("encode", 0, 0, "VAE-encoding the render");
  models::CogVideoXVae vae(ctx, o.model / "vae");
  const float sf = float(vae.config().scaling_factor);
  Tensor render_video = video_to_device(ctx, in.render);
  models::VaePosterior post = vae.encode(render_video);
  Tensor x0_mean = to_diffusion_layout(ctx, post.mean, sf);
  Tensor x0 = st.official ? to_diffusion_layout(ctx, posterior_sample(ctx, post, o.seed, 101), sf) : x0_mean;
  HostTensor first({1, 3, 1, o.render.height, o.render.width}, DType::f32);  // frame 0 of [F,3,H,W]
  std::memcpy(first.data.data(), in.render.data.data(), first.bytes());
  models::VaePosterior img_post = vae.encode(Tensor::upload(ctx, first));
  Tensor img0 = to_diffusion_layout(ctx, st.official ? posterior_sample(ctx, img_post, o.seed, 102) : img_post.mean, sf);
  const Shape lat = x0.shape();  // [Fl, C, h, w]
  Tensor image_latent = Tensor::zeros(ctx, lat, DType::f32, "image latent");
  ops::run_now(ctx, [&](vk::Recorder& rec) { rec.copy(img0.buffer(), image_latent.buffer(), img0.bytes()); });
  end_stage("encode");

  // 4. Text.
  say("text", 0, 0, "encoding the prompts");
  models::T5Encoder t5(ctx, o.model / "text_encoder");
  Tensor text = t5.encode_prompts(tokenizer, {st.negative, o.prompt}, text_len);     // [uncond; cond]
  Tensor text_inv = t5.encode_prompts(tokenizer, {""}, text_len);  // inversion: "", no guidance (the official
                                                                   // CFG over two identical "" rows is a no-op)
  end_stage("text");

  // 5. Inversion (cached on disk).
  models::CogVideoXTransformer transformer(ctx, o.model / "transformer");
  const int t0 = plan.t0();
  std::vector<diffusion::StepCoefficients> inv_steps =
      st.official ? diffusion::inversion_steps_official(diffusion::DDIMInverseSchedule(schedule.config()), st.inversion_steps)
                  : diffusion::inversion_steps_paper(schedule, t0, st.inversion_steps);
  InversionCache cache(o.cache_dir);
  // Keyed by what determines x0 and the image latent (the splat's float atomics may reorder sums, so the
  // rendered bytes themselves are not a stable key).
  const RenderJob& j = o.render;
  const std::string key = InversionCache::key(
      {model_fingerprint(o.model), file_fingerprint(j.video), file_fingerprint(j.depth), j.trajectory,
       std::to_string(F) + "x" + std::to_string(j.height) + "x" + std::to_string(j.width), j.squash ? "squash" : "crop",
       j.metric_depth ? "depth" : "disparity", j.hard_points ? "points" : "soft",
       std::to_string(j.fx) + "," + std::to_string(j.fy) + "," + std::to_string(j.cx) + "," + std::to_string(j.cy),
       o.preset, std::to_string(st.inversion_steps), std::to_string(t0)});
  Tensor eps_inv;
  if (o.use_cache) eps_inv = cache.load(ctx, key, lat);
  report.inversion_from_cache = eps_inv.defined();
  if (!eps_inv.defined()) {
    TransformerDenoiser model_inv(ctx, transformer, image_latent, text_inv, 1);
    diffusion::LoopCallbacks cb;
    cb.progress = [&](int step, int total, int t) { say("invert", step, total, "t=" + std::to_string(t)); };
    eps_inv = diffusion::invert(ctx, x0_mean, inv_steps, std::ref(model_inv), {false, 1.0}, cb);
    if (o.use_cache) cache.store(ctx, key, eps_inv);
  } else {
    say("invert", 1, 1, "inversion loaded from the cache");
  }
  end_stage("invert");

  // 6–7. SLM and adaptive K-RNR.
  say("init_noise", 0, 0, "stochastic latent modulation and K-RNR");
  diffusion::SlmOptions slm;
  slm.preset = st.official ? diffusion::SlmOptions::Preset::official : diffusion::SlmOptions::Preset::paper;
  slm.seed = o.seed;
  diffusion::SlmMasks masks = diffusion::compute_slm_masks(ctx, in.mask, &in.depth, true, int(lat[0]), slm);
  diffusion::SlmPlan slm_plan = diffusion::make_slm_plan(ctx, masks, int(lat[1]), slm.scope);
  Tensor x0_mod = Tensor::empty(ctx, lat, DType::f32, "x0"), eps_mod = Tensor::empty(ctx, lat, DType::f32, "eps");
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    rec.copy(x0.buffer(), x0_mod.buffer(), x0.bytes());
    rec.copy(eps_inv.buffer(), eps_mod.buffer(), eps_inv.bytes());
  });
  const double abar = schedule.alpha_cumprod(t0);
  Tensor x_init;
  if (!st.official) {
    ops::run_now(ctx, [&](vk::Recorder& rec) { diffusion::apply_slm(rec, x0_mod, eps_mod, slm_plan, o.seed, 0); });
    x_init = diffusion::adaptive_krnr_paper(ctx, x0_mod, eps_mod, abar, o.k, st.delta);
  } else {  // three rounds of SLM + per-element K-RNR, each output the next ε
    Tensor mu = to_diffusion_layout(ctx, post.mean, sf), sigma = to_diffusion_layout(ctx, post.std, sf);
    for (int round = 0; round < 3; ++round) {
      ops::run_now(ctx, [&](vk::Recorder& rec) { diffusion::apply_slm(rec, x0_mod, eps_mod, slm_plan, o.seed, round); });
      eps_mod = diffusion::adaptive_krnr_official(ctx, x0_mod, eps_mod, mu, sigma, abar, int(o.k), int(st.delta), 1);
    }
    x_init = eps_mod;
  }
  end_stage("init_noise");

  // 8. Sampling with classifier-free guidance.
  TransformerDenoiser model(ctx, transformer, image_latent, text, 2);
  diffusion::LoopCallbacks cb;
  cb.progress = [&](int step, int total, int t) { say("sample", step, total, "t=" + std::to_string(t)); };
  diffusion::SampleResult result = diffusion::sample(ctx, x_init, schedule, plan, std::ref(model), {true, o.guidance}, cb);
  end_stage("sample");

  // 9. Decode and write.
  say("decode", 0, 0, "VAE-decoding the result");
  Tensor frames = vae.decode(to_vae_layout(ctx, result.pred_x0, 1.0f / sf));
  HostTensor output = video_to_host(ctx, frames);
  for (int64_t i = 0; i < output.numel(); ++i) output.as<float>()[i] = std::clamp(output.as<float>()[i], -1.0f, 1.0f);
  end_stage("decode");

  const auto& dir = o.render.out_dir;
  report.output_mp4 = dir / "output.mp4";
  report.render_mp4 = dir / "render.mp4";
  report.mask_mp4 = dir / "mask.mp4";
  report.comparison_mp4 = dir / "comparison.mp4";
  report.run_json = dir / "run.json";
  write_video(report.render_mp4, in.render, in.fps);
  write_video(report.mask_mp4, mask_as_video(in.mask), in.fps);
  write_video(report.comparison_mp4, hstack_videos({&in.rgb, &in.render, &output}), in.fps);
  write_video(report.output_mp4, output, in.fps);
  end_stage("write");
  report.peak_device_bytes = ctx.allocator().stats().peak_bytes_in_use;
  write_run_record(report.run_json, o, report, RunRecordExtras{st.steps, st.strength, st.inversion_steps, st.delta,
                                                                st.negative, t0, plan.num_steps(), ctx.caps().name,
                                                                ctx.caps().driver_name + " " + ctx.caps().driver_info,
                                                                model_fingerprint(o.model), masks.source_fell_back});
  return report;
}

}  // namespace dvs
