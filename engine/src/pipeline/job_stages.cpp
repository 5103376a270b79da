#include "pipeline/job_stages.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>

#include "diffusion/sampler.hpp"
#include "dvs/error.hpp"
#include "io/injected_faults.hpp"
#include "io/library_log.hpp"
#include "io/option_names.hpp"
#include "models/cogvideox/lora.hpp"
#include "models/cogvideox/vae_tiling.hpp"
#include "pipeline/denoise_stages.hpp"
#include "pipeline/depth_source.hpp"
#include "pipeline/inversion_cache.hpp"
#include "pipeline/latent_layout.hpp"
#include "pipeline/memory_advice.hpp"
#include "pipeline/memory_plan.hpp"
#include "pipeline/run_outputs.hpp"
#include "tensor/ops_check.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs {

JobPlan plan_job(const RunOptions& o) {
  Settings st = resolve(o);
  if (!std::filesystem::is_directory(o.model))
    throw Error(o.model.string() + ": no such model folder (give " + option_name("RunOptions::model") +
                " a folder laid out like THUDM/CogVideoX-5b-I2V)");
  if (!o.lora.empty() && !std::filesystem::is_regular_file(o.lora))
    throw Error(o.lora.string() + ": no such LoRA file (give " + option_name("RunOptions::lora") + " a .safetensors file)");
  // Cheap checks of the model before any long work.
  diffusion::CogVideoXSchedule schedule(diffusion::load_scheduler_config(o.model));
  diffusion::SamplingPlan plan = schedule.plan(st.steps, st.strength);
  T5Tokenizer tokenizer = T5Tokenizer::load(o.model);
  const int text_len = max_text_seq_length(o.model);
  return JobPlan{std::move(st), std::move(schedule), std::move(plan), std::move(tokenizer), text_len};
}

std::optional<models::VaeTiling> vae_tiling(const RunOptions& o) {
  if (!o.vae_tiling) return std::nullopt;
  models::VaeTiling t;
  t.tile_sample_min_height = o.vae_tile_height;
  t.tile_sample_min_width = o.vae_tile_width;
  return t;
}

void check_tiles_join(const models::VaeConfig& cfg, const models::VaeTiling& tiling) {
  // diffusers keeps `stride` of each tile and moves by `stride` in the input; unless both are the same distance
  // in pixels, the tiles overlap or leave gaps and the result has the wrong size.
  const int64_t r = cfg.spatial_ratio();
  const auto enc = models::TilePlan::for_encode(cfg, tiling), dec = models::TilePlan::for_decode(cfg, tiling);
  if (enc.stride_h != enc.limit_h * r || enc.stride_w != enc.limit_w * r || dec.stride_h * r != dec.limit_h ||
      dec.stride_w * r != dec.limit_w)
    throw Error(option_name("RunOptions::vae_tile_height/width") + " " + std::to_string(enc.tile_in_h) + "x" + std::to_string(enc.tile_in_w) +
                ": tiles of this size do not join exactly (the tile stride, 5/6 of the height and 4/5 of the width, "
                "must be a whole number of " + std::to_string(r) + "-pixel cells); use e.g. 240x360 (the default), 96x160 or 48x40");
}

nlohmann::json depth_stage(RunOptions& o, StageTracker& stages) {
  if (o.render.depth_model.empty()) return nullptr;
  // Said as it is: reading the cache takes a moment, estimating may take long.
  stages.begin("depth", depth_cache_has(depth_job_for(o.render, o.cache_dir, !o.use_cache))
                            ? "reading the cached estimate of " + o.render.depth_model.filename().string()
                            : "estimating depth with " + o.render.depth_model.filename().string());
  nlohmann::json d = resolve_depth_model(
      o.render, o.cache_dir, !o.use_cache,
      [&](const std::string&, int step, int total, const std::string& note) { stages.say(step, total, note); },
      [&] {
        stages.check_cancelled();
        return false;
      });
  stages.end();
  return d;
}

RenderedInput render_for_model(vk::Context& ctx, const RunOptions& o, StageTracker& stages) {
  stages.begin("render", "decoding and rendering");
  RenderedInput in = render_stage(ctx, o.render, [&](const std::string& s) { stages.say(0, 0, s); });
  const int F = int(in.rgb.shape[0]);
  if ((F - 1) % 4 != 0)
    throw Error(o.render.video.string() + ": " + std::to_string(F) + " frames were decoded; the model needs 4k+1 — set " +
                option_name("RunOptions::render.frames"));
  stages.end();
  return in;
}

EncodedRender encode_render(vk::Context& ctx, models::CogVideoXVae& vae, const RunOptions& o, const Settings& st,
                            const RenderedInput& in) {
  const auto tiling = vae_tiling(o);
  if (tiling) check_tiles_join(vae.config(), *tiling);
  auto encode = [&](const Tensor& video) { return tiling ? vae.encode_tiled(video, *tiling) : vae.encode(video); };
  EncodedRender e;
  e.scaling = float(vae.config().scaling_factor);
  const Tensor video = video_to_device(ctx, in.render);
  ops::require_finite(ctx, {{&video, "render"}}, kNonFiniteHint);
  e.posterior = encode(video);
  e.x0_mean = to_diffusion_layout(ctx, e.posterior.mean, e.scaling);
  e.x0 = st.official ? to_diffusion_layout(ctx, posterior_sample(ctx, e.posterior, o.seed, 101), e.scaling) : e.x0_mean;
  models::VaePosterior img_post = encode(Tensor::upload(ctx, first_frame(in.render)));
  e.image_latent = image_latent(ctx, st.official ? posterior_sample(ctx, img_post, o.seed, 102) : img_post.mean, e.x0.dim(0), e.scaling);
  std::vector<std::pair<const Tensor*, std::string>> results = {{&e.x0_mean, "x0 (the render's latent)"},
                                                                 {&e.image_latent, "image latent"}};
  if (st.official) results.push_back({&e.x0, "x0 (posterior sample)"});  // otherwise the same tensor as x0_mean
  ops::require_finite(ctx, results, kNonFiniteHint);
  return e;
}

HostTensor decode_latent(vk::Context& ctx, models::CogVideoXVae& vae, const RunOptions& o, const Tensor& latent, float scaling,
                         int frames) {
  const auto tiling = vae_tiling(o);
  Tensor z = to_vae_layout(ctx, latent, 1.0f / scaling);
  const Tensor decoded = tiling ? vae.decode_tiled(z, *tiling) : vae.decode(z);
  ops::require_finite(ctx, {{&decoded, "decoded frames"}}, kNonFiniteHint);
  HostTensor all = video_to_host(ctx, decoded);
  const int64_t got = all.shape[0];
  // diffusers' decoder batches latent frames as [0 : 2 + Fl mod 2], then 2 at a time, and its temporal
  // upsampling keeps a batch's first frame apart only when the batch is odd. With an even Fl the first batch
  // is even, so latent frame 0 (which encodes video frame 0 alone) comes out as 4 frames instead of 1: 4·Fl
  // frames for a 4·Fl − 3 frame video, the first 3 being extra copies of frame 0. They are dropped, which
  // aligns every later frame with the render's.
  if (got != frames && !(got == frames + 3 && latent.dim(0) % 2 == 0))
    throw Error("internal: the VAE decoded " + std::to_string(got) + " frames from " + std::to_string(latent.dim(0)) +
                " latent frames; expected " + std::to_string(frames));
  const int64_t skip = got - frames;
  const Shape& s = all.shape;  // [F,3,H,W]
  HostTensor out({frames, s[1], s[2], s[3]}, DType::f32);
  std::memcpy(out.data.data(), all.as<float>() + skip * s[1] * s[2] * s[3], out.bytes());
  for (int64_t i = 0; i < out.numel(); ++i) out.as<float>()[i] = std::clamp(out.as<float>()[i], -1.0f, 1.0f);
  return out;
}

nlohmann::json WeightsUsed::record(const std::string& requested) const {
  auto name = [](const std::optional<models::WeightResidency>& r) { return r ? models::residency_name(*r) : "not loaded"; };
  return {{"requested", requested}, {"transformer", name(transformer)}, {"text_encoder", name(text_encoder)}};
}

WeightResidencies weight_residencies(const vk::Context& ctx, const RunOptions& o) {
  using models::WeightResidency;
  const pipeline::WeightsChoice choice = pipeline::parse_weights_choice(o.weights, option_name("RunOptions::weights"));
  if (choice != pipeline::WeightsChoice::automatic) {
    const WeightResidency r = choice == pipeline::WeightsChoice::stream ? WeightResidency::stream : WeightResidency::resident;
    return {r, r};
  }
  // The preflight's plan (memory_advice.hpp): the device's memory and limits, the run's size and tiling.
  const pipeline::MemoryPlan plan = pipeline::plan_memory(pipeline::plan_model_from_folder(o.model), run_plan_request(o, ctx.caps()));
  return {pipeline::planned_residency(plan, "transformer"), pipeline::planned_residency(plan, "text_encoder")};
}

std::unique_ptr<models::CogVideoXTransformer> load_transformer(vk::Context& ctx, const RunOptions& o,
                                                               models::WeightResidency residency) {
  auto transformer = std::make_unique<models::CogVideoXTransformer>(ctx, o.model / "transformer", residency);
  if (!o.lora.empty()) {
    try {
      transformer->set_lora(models::load_lora(ctx, o.lora, float(o.lora_scale)));
    } catch (const Error& e) {
      throw Error(option_name("RunOptions::lora") + " " + o.lora.string() + ": " + e.what(), e.kind());
    }
  }
  return transformer;
}

namespace {

// The camera as used (not as given: the default and the same values typed out, as `dvs run --from` does, render
// the same and share the cache entry), at full precision.
std::string intrinsics_key(const geometry::Intrinsics& K) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "%.17g,%.17g,%.17g,%.17g", K.fx, K.fy, K.cx, K.cy);
  return buf;
}

// The splat's float atomics may reorder sums, so the rendered bytes themselves are not a stable key: the
// inputs and render options that determine them are.
std::vector<std::string> render_key_parts(const RunOptions& o, int frames, const std::vector<std::string>& input) {
  const RenderJob& j = o.render;
  // --depth-fit and --trim-depth decide which depth pixels and frames meet which video ones.
  std::vector<std::string> parts{model_fingerprint(o.model)};
  parts.insert(parts.end(), input.begin(), input.end());
  parts.insert(parts.end(), {std::to_string(frames) + "x" + std::to_string(j.height) + "x" + std::to_string(j.width),
                             j.squash ? "squash" : "crop", j.metric_depth ? "depth" : "disparity",
                             j.hard_points ? "points" : "soft", intrinsics_key(job_intrinsics(j)), "fit " + j.depth_fit,
                             j.trim_depth ? "trim" : "no trim"});
  return parts;
}

std::string exact(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

}  // namespace

std::vector<std::string> file_input_key(const RunOptions& o) {
  const RenderJob& j = o.render;
  return {file_fingerprint(j.video), file_fingerprint(j.depth), j.trajectory};
}

std::string latent_cache_key(const RunOptions& o, const JobPlan& jp, int frames, bool dynamic_cfg) {
  return latent_cache_key(o, jp, frames, dynamic_cfg, file_input_key(o));
}

std::string latent_cache_key(const RunOptions& o, const JobPlan& jp, int frames, bool dynamic_cfg,
                             const std::vector<std::string>& input) {
  const Settings& st = jp.settings;
  // Everything the sampled latent depends on except the VAE options (--vae-tiling, --vae-tile) and the device:
  // a run whose decode failed is re-run with other ones and reuses the latent (run.json records the VAE
  // options it was encoded with).
  std::vector<std::string> parts = render_key_parts(o, frames, input);
  parts.insert(parts.end(),
               {"latent v1", o.render.depth_fit, o.render.trim_depth ? "trim" : "no trim", o.preset,
                std::to_string(st.steps), exact(st.strength), std::to_string(st.inversion_steps),
                std::to_string(jp.plan.t0()), exact(st.delta), st.negative, o.prompt, exact(o.guidance), exact(o.k),
                dynamic_cfg ? "dynamic cfg " + exact(o.preservation_scale) : "constant cfg", std::to_string(o.seed),
                o.lora.empty() ? "no lora" : "lora " + file_fingerprint(o.lora) + " " + exact(o.lora_scale)});
  return InversionCache::key(parts);
}

LatentCache::LatentCache(const RunOptions& o, std::string key) : cache_(o.cache_dir, "latent"), key_(std::move(key)) {}

std::filesystem::path LatentCache::file() const { return cache_.file(key_); }

std::filesystem::path LatentCache::meta_file() const {
  std::filesystem::path f = file();
  return f.replace_extension(".json");
}

std::optional<CachedLatent> LatentCache::load(vk::Context& ctx, const Shape& shape, std::string* rejected) const {
  std::error_code ec;
  if (!std::filesystem::exists(meta_file(), ec) || !std::filesystem::exists(file(), ec)) return std::nullopt;
  CachedLatent c;
  try {
    c.meta = nlohmann::json::parse(std::ifstream(meta_file()));
  } catch (const nlohmann::json::exception&) {
    std::filesystem::remove(meta_file(), ec);
    if (rejected) *rejected = meta_file().string() + ": not JSON; removed, sampling again";
    return std::nullopt;
  }
  c.latent = cache_.load(ctx, key_, shape, rejected);
  if (!c.latent.defined()) return std::nullopt;
  return c;
}

std::string LatentCache::store(vk::Context& ctx, const Tensor& latent, const nlohmann::json& meta) const {
  // The metadata first, then the latent (written under a temporary name and renamed): a latent file is
  // there only complete and with its metadata.
  std::error_code ec;
  std::filesystem::create_directories(cache_.dir(), ec);
  const std::filesystem::path tmp = meta_file().string() + ".partial-" + std::to_string(::getpid());
  {
    std::ofstream out(tmp);
    out << meta.dump(2) << "\n";
    if (!out || faults::write_error(meta_file())) {
      std::filesystem::remove(tmp, ec);
      return meta_file().string() + ": could not be written";
    }
  }
  std::filesystem::rename(tmp, meta_file(), ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    return meta_file().string() + ": " + ec.message();
  }
  std::string failed = cache_.store(ctx, key_, latent);
  if (!failed.empty()) std::filesystem::remove(meta_file(), ec);  // no metadata without its latent
  remove_stale_temporaries(meta_file());  // what a store killed earlier left
  return failed;
}

std::string inversion_cache_key(const RunOptions& o, const JobPlan& jp, int frames) {
  return inversion_cache_key(o, jp, frames, file_input_key(o));
}

std::string inversion_cache_key(const RunOptions& o, const JobPlan& jp, int frames, const std::vector<std::string>& input) {
  const Settings& st = jp.settings;
  // Keyed by what the inversion reads: x0 (the render, encoded with or without tiling), the image latent (a
  // posterior sample drawn with the seed under the official preset, the mean under paper), the schedule up to
  // t0, and the transformer with its LoRA. Not the prompt, negative prompt, guidance or k: the inversion runs
  // on the empty prompt without guidance.
  const auto tiling = vae_tiling(o);
  std::vector<std::string> parts = render_key_parts(o, frames, input);
  parts.insert(parts.end(),
               {o.preset, std::to_string(st.inversion_steps), std::to_string(jp.plan.t0()),
                st.official ? "image latent sampled with seed " + std::to_string(o.seed) : "image latent mean",
                o.lora.empty() ? "no lora" : "lora " + file_fingerprint(o.lora) + " " + exact(o.lora_scale),
                tiling ? "tiled " + std::to_string(tiling->tile_sample_min_height) + "x" + std::to_string(tiling->tile_sample_min_width)
                       : "untiled"});
  return InversionCache::key(parts);
}

InversionResult invert_render(vk::Context& ctx, models::CogVideoXTransformer& transformer, const RunOptions& o,
                              const JobPlan& jp, int frames, const EncodedRender& enc, const Tensor& text_empty,
                              StageTracker& stages) {
  return invert_render(ctx, transformer, o, jp, frames, file_input_key(o), enc, text_empty, stages);
}

InversionResult invert_render(vk::Context& ctx, models::CogVideoXTransformer& transformer, const RunOptions& o,
                              const JobPlan& jp, int frames, const std::vector<std::string>& input,
                              const EncodedRender& enc, const Tensor& text_empty, StageTracker& stages) {
  const Settings& st = jp.settings;
  const int t0 = jp.plan.t0();
  const std::string key = inversion_cache_key(o, jp, frames, input);
  InversionCache cache(o.cache_dir);
  InversionResult r;
  if (o.use_cache) {
    r.cache_file = cache.file(key);
    std::string rejected;
    r.eps = cache.load(ctx, key, enc.x0_mean.shape(), &rejected);
    if (!rejected.empty()) log_warning("ignoring the cached inversion " + rejected);
  }
  r.from_cache = r.eps.defined();
  if (r.from_cache) {
    stages.say(1, 1, "inversion loaded from the cache");
    return r;
  }
  ops::NonFiniteCheck check(ctx);
  r.eps = invert_latent(ctx, transformer, inversion_steps(st, jp.schedule, t0), enc.x0_mean, enc.image_latent, text_empty,
                        stages.loop_callbacks(&check), &check);
  ops::require_finite(ctx, {{&r.eps, "ε_inv"}}, kNonFiniteHint);  // before it is cached
  if (o.use_cache) {
    if (const std::string failed = cache.store(ctx, key, r.eps); !failed.empty()) {
      log_warning("the inversion could not be cached (" + failed + "); a later run computes it again");
      r.cache_file.clear();
    }
  }
  return r;
}

}  // namespace dvs
