// The golden end-to-end pipeline fixture shared by golden_pipeline_e2e.cpp and golden_forced_limits.cpp: the
// pack's options, loaders and the stage checks (see golden_pipeline_e2e.cpp for what they compare).
#pragma once
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "diffusion/init_noise.hpp"
#include "diffusion/sampler.hpp"
#include "diffusion/schedule.hpp"
#include "io/npy.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "pipeline/denoise_stages.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/latent_layout.hpp"
#include "pipeline/stage_tracker.hpp"
#include "support/files.hpp"
#include "support/golden_compare.hpp"
#include "support/gpu.hpp"
#include "support/pack.hpp"
#include "support/precision_rule.hpp"
#include "tensor/dispatch.hpp"

namespace dvs::e2e {

using test::GpuTest;

inline HostTensor load(const std::string& rel) { return test::pack_npy(rel); }
inline const nlohmann::json& settings() { return test::pack_cases().at("e2e_settings"); }

// `ours` against the pack file `rel` by the precision rule (support/precision_rule.hpp) for the ops that made it:
// by default the chain's (VAE convolutions and the transformer's linears and attention).
inline void expect_close(const std::string& what, const Tensor& ours, vk::Context& ctx, const std::string& rel,
                         const test::PackTolerance& tol, unsigned ops = test::kAllKernelOps) {
  test::expect_golden(what, ours.download(ctx), rel, tol.atol, tol.rtol, ops);
}

// The options a user would give for the pack's e2e case: the official preset (zero-SNR inversion to 999, K-RNR
// with δ = 2 in 3 rounds) with the pack's step counts, strength, guidance and seed; no cache.
inline RunOptions pack_options() {
  RunOptions o;
  o.model = test::golden_path() / "model";
  o.preset = "official";
  o.steps = settings().at("num_inference_steps");
  o.strength = settings().at("strength");
  o.inversion_steps = settings().at("num_inversion_steps");
  o.k = settings().at("k_order");
  o.delta = settings().at("delta_official");
  o.guidance = settings().at("guidance_scale");
  o.seed = settings().at("generator_seed");
  o.use_cache = false;
  return o;
}

// [1, C, F, H, W] (the pack's videos) -> [F, C, H, W] (the pipeline's host videos).
inline HostTensor frames_first(const HostTensor& v) {
  const int64_t C = v.shape[1], F = v.shape[2], HW = v.shape[3] * v.shape[4];
  HostTensor out({F, C, v.shape[3], v.shape[4]}, DType::f32);
  const std::vector<float> x = v.to_f32();
  for (int64_t c = 0; c < C; ++c)
    for (int64_t f = 0; f < F; ++f)
      std::copy_n(x.begin() + (c * F + f) * HW, HW, out.as<float>() + (f * C + c) * HW);
  return out;
}

// The pack's file for step `i` at timestep `t` of a loop ("inversion" or "sampling").
inline std::string step_file(const std::string& loop, size_t i, int t, const std::string& what) {
  return "e2e/" + loop + "_step" + std::to_string(i) + "_t" + std::to_string(t) + "_" + what + ".npy";
}

// Records every step's latent (a copy: the loop reuses its buffers).
struct LatentLog {
  std::map<int, HostTensor> by_timestep;
  diffusion::LoopCallbacks callbacks(vk::Context& ctx) {
    diffusion::LoopCallbacks cb;
    cb.latent = [this, &ctx](int, int t, const Tensor& x) { by_timestep[t] = x.download(ctx); };
    return cb;
  }
};

class PipelineE2e : public GpuTest {
 protected:
  models::CogVideoXTransformer& transformer() {
    if (!transformer_) transformer_ = std::make_unique<models::CogVideoXTransformer>(ctx(), test::golden_path() / "model" / "transformer");
    return *transformer_;
  }
  models::CogVideoXVae& vae() {
    if (!vae_) vae_ = std::make_unique<models::CogVideoXVae>(ctx(), test::golden_path() / "model" / "vae");
    return *vae_;
  }
  Tensor upload(const HostTensor& h) { return Tensor::upload(ctx(), h); }
  Tensor pack(const std::string& rel) { return upload(without_batch(load(rel))); }
  static HostTensor without_batch(HostTensor h) {
    h.shape = test::without_batch(h.shape);
    return h;
  }

  // The production inversion (invert_latent over inversion_steps of the plan) from x0; checks every level's
  // latent and ε_inv against the pack. Returns ε_inv.
  Tensor invert_and_check(const JobPlan& jp, const Tensor& x0, const Tensor& image_latent, const Tensor& text) {
    const auto tol = test::pack_tolerance("e2e_inversion");
    const std::vector<float> ts = load("e2e/inversion_timesteps.npy").to_f32();
    const auto steps = inversion_steps(jp.settings, jp.schedule, jp.plan.t0());
    EXPECT_EQ(steps.size(), ts.size()) << "inversion steps";
    LatentLog log;
    const Tensor eps = invert_latent(ctx(), transformer(), steps, x0, image_latent, text, log.callbacks(ctx()));
    for (size_t i = 0; i < ts.size(); ++i) {
      const int t = int(ts[i]);
      const std::string f = step_file("inversion", i, t, "latent");
      if (!log.by_timestep.count(t)) {
        ADD_FAILURE() << "the inversion never reached the pack's level " << t;
        continue;
      }
      test::expect_golden("inversion latent at t=" + std::to_string(t), log.by_timestep.at(t), f, tol.atol, tol.rtol,
                          test::kAllKernelOps);
    }
    expect_close("eps_inv", eps, ctx(), "e2e/eps_inv.npy", tol);
    return eps;
  }

  // The production guided sampling from x_init over `plan`; checks every step's latent against the pack files
  // named by `ts` and returns the result.
  diffusion::SampleResult sample_and_check(const JobPlan& jp, const diffusion::SamplingPlan& plan, const Tensor& x_init,
                                           const Tensor& image_latent, const std::string& case_name, bool check_steps) {
    const auto tol = test::pack_tolerance(case_name);
    const Tensor text = guidance_text(ctx(), upload(load("e2e/negative_embeds.npy")),
                                      upload(load("e2e/prompt_embeds.npy")));
    LatentLog log;
    diffusion::Guidance guidance{true, settings().at("guidance_scale")};
    diffusion::SampleResult r =
        sample_latent(ctx(), transformer(), jp.schedule, plan, x_init, image_latent, text, guidance, log.callbacks(ctx()));
    EXPECT_EQ(log.by_timestep.size(), plan.timesteps.size()) << "steps run";
    if (check_steps) {
      const std::vector<float> ts = load("e2e/sampling_timesteps.npy").to_f32();
      for (size_t i = 0; i < ts.size(); ++i) {
        const int t = int(ts[i]);
        if (!log.by_timestep.count(t)) {
          ADD_FAILURE() << "the sampling never ran the pack's timestep " << t;
          continue;
        }
        test::expect_golden("sampling latent after t=" + std::to_string(t), log.by_timestep.at(t),
                            step_file("sampling", i, t, "latent"), tol.atol, tol.rtol, test::kAllKernelOps);
      }
    }
    return r;
  }

  // decode_latent (what `dvs run` writes, clamped to [−1, 1]) against the pack's unclamped frames, clamped.
  void check_frames(const Tensor& latent) {
    const double atol = test::pack_case("e2e_sampling").at("tolerance").at("frames_atol");
    // The golden's frames (and its bf16 run's, the same way) frame-first and clamped.
    auto clamped = [](const HostTensor& pack_frames) {
      HostTensor f = frames_first(pack_frames);
      for (int64_t i = 0; i < f.numel(); ++i) f.as<float>()[i] = std::clamp(f.as<float>()[i], -1.0f, 1.0f);
      return f;
    };
    const test::PackGolden pg = test::read_pack_golden(test::golden_path(), "e2e/final_frames.npy");
    const HostTensor golden = clamped(pg.golden);
    std::optional<std::vector<float>> bf16;
    if (pg.bf16) bf16 = clamped(*pg.bf16).to_f32();
    const HostTensor frames = decode_latent(ctx(), vae(), pack_options(), latent, float(vae().config().scaling_factor),
                                              int(golden.shape[0]));
    test::expect_golden_values("final frames (clamped)", frames.shape, frames.to_f32(), golden.shape, golden.to_f32(),
                               bf16, pg.bf16_path.string(), atol, 0, test::kAllKernelOps);
  }

  // The production image latent of the video's first frame: VAE posterior of frame 0 alone, mean + std · the
  // pack's draw, scaled into latent frame 0 of `latent_frames`.
  Tensor image_latent_of(const HostTensor& video_frames, int64_t latent_frames) {
    const models::VaePosterior post = vae().encode(upload(first_frame(video_frames)));
    const Tensor noise = upload(load("e2e/image_sample_noise.npy"));
    Tensor sample = Tensor::empty(ctx(), post.mean.shape(), DType::f32);
    ops::run_now(ctx(), [&](vk::Recorder& rec) { models::CogVideoXVae::sample(rec, post, noise, sample); });
    return image_latent(ctx(), sample, latent_frames, float(vae().config().scaling_factor));
  }

  // The golden chain from the video (encode, invert, K-RNR, sample, decode), each stage fed the previous
  // stage's result, every result compared with the pack (PipelineE2e.ChainedFromTheVideo, ForcedLimits).
  void chained_from_the_video() {
    const RunOptions o = pack_options();
    const JobPlan jp = plan_job(o);
    const float sf = float(vae().config().scaling_factor);
    const HostTensor video = frames_first(load("vae/video.npy"));
    RenderedInput in;
    in.render = video;
    EncodedRender enc = encode_render(ctx(), vae(), o, jp.settings, in);  // x0_mean, posterior; its Philox draws unused
    const auto img_tol = test::pack_tolerance("e2e_image_latents");
    expect_close("x0 (0.7 · posterior mean)", enc.x0_mean, ctx(), "e2e/inversion_x0.npy", img_tol);
    const Tensor image_latent = image_latent_of(video, enc.x0_mean.dim(0));
    expect_close("image_latents", image_latent, ctx(), "e2e/image_latents.npy", img_tol);

    const Tensor empty_text = upload(load("e2e/empty_embeds.npy"));
    const Tensor eps = invert_and_check(jp, enc.x0_mean, image_latent, empty_text);
    // invert_render as `dvs run` calls it (cache off), on the EncodedRender with the pack's image-latent draw in
    // place of the Philox one: it must invert x0_mean (not the sampled x0) with that image latent.
    enc.image_latent = image_latent;
    StageTracker stages({}, {});
    const InversionResult inv = invert_render(ctx(), transformer(), o, jp, int(video.shape[0]), enc, empty_text, stages);
    EXPECT_FALSE(inv.from_cache);
    expect_close("eps_inv (invert_render)", inv.eps, ctx(), "e2e/eps_inv.npy", test::pack_tolerance("e2e_inversion"));

    Tensor sample = Tensor::empty(ctx(), enc.posterior.mean.shape(), DType::f32);
    const Tensor noise = upload(load("e2e/video_sample_noise.npy"));
    ops::run_now(ctx(), [&](vk::Recorder& rec) { models::CogVideoXVae::sample(rec, enc.posterior, noise, sample); });
    enc.x0 = to_diffusion_layout(ctx(), sample, sf);  // the pack's draw in place of the Philox one
    expect_close("x0 (0.7 · posterior sample)", enc.x0, ctx(), "e2e/krnr_x0.npy", img_tol);
    const Tensor x_init =
        initial_latent(ctx(), jp.settings, o.k, o.seed, enc, eps, nullptr, jp.schedule.alpha_cumprod(jp.plan.t0()));
    expect_close("x_init", x_init, ctx(), "e2e/x_init.npy", test::pack_tolerance("e2e_krnr"));

    const diffusion::SampleResult r = sample_and_check(jp, jp.plan, x_init, image_latent, "e2e_sampling", true);
    expect_close("final latent", r.pred_x0, ctx(), "e2e/final_latent.npy", test::pack_tolerance("e2e_sampling"));
    check_frames(r.pred_x0);
  }

  int64_t latent_frames() { return load("e2e/video_posterior_mean.npy").shape.at(2); }  // [1, C, Fl, h, w]

 private:
  std::unique_ptr<models::CogVideoXTransformer> transformer_;
  std::unique_ptr<models::CogVideoXVae> vae_;
};

}  // namespace dvs::e2e
