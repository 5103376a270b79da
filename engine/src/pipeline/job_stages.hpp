// The stages that `dvs run` (run_pipeline) and `dvs invert` (run_inversion) share, each implemented once:
// planning from the options and the model's small files, VAE encoding of the render, the LoRA, the DDIM
// inversion with its on-disk cache, and VAE decoding.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "diffusion/schedule.hpp"
#include "dvs/pipeline.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/tokenizer.hpp"
#include "pipeline/inversion_cache.hpp"
#include "pipeline/render_stage.hpp"
#include "pipeline/settings.hpp"
#include "pipeline/stage_tracker.hpp"

namespace dvs {

// Everything decided before device work: checked settings, the schedule and the tokenizer.
struct JobPlan {
  Settings settings;
  diffusion::CogVideoXSchedule schedule;
  diffusion::SamplingPlan plan;
  T5Tokenizer tokenizer;
  int text_len = 0;
};

// Checks the options and reads the model's small files (configs, vocabulary); errors name the option or file.
JobPlan plan_job(const RunOptions& o);

// Stages 1–2: decode and render, checking that the model can take the frame count (4k+1).
// --depth-model: stage "depth" estimates the clip's depth (or finds it in the cache) and points o.render.depth at
// it; returns its provenance for run.json (null without --depth-model).
nlohmann::json depth_stage(RunOptions& o, StageTracker& stages);

RenderedInput render_for_model(vk::Context& ctx, const RunOptions& o, StageTracker& stages);

// The render in latent space (diffusion layout [Fl, C, h, w]).
struct EncodedRender {
  models::VaePosterior posterior;  // of the whole render, VAE units
  Tensor x0_mean;                  // scaled posterior mean: what the inversion starts from
  Tensor x0;                       // = x0_mean (paper) or a posterior sample (official)
  Tensor image_latent;             // frame 0's latent in latent frame 0, zeros after (CogVideoX I2V)
  float scaling = 1;               // the VAE's scaling_factor
};

EncodedRender encode_render(vk::Context& ctx, models::CogVideoXVae& vae, const RunOptions& o, const Settings& st,
                            const RenderedInput& in);

// latent [Fl, C, h, w] (diffusion units) -> `frames` frames [frames, 3, H, W] clamped to [−1, 1] on the host
// (the render's count: with an even Fl the VAE decodes 3 more, see the .cpp). NaN/Inf in them is an error.
HostTensor decode_latent(vk::Context& ctx, models::CogVideoXVae& vae, const RunOptions& o, const Tensor& latent, float scaling,
                         int frames);

// Throws dvs::Error when tiles of this size do not join exactly (run's check of --vae-tile; dvs plan offers
// only sizes it accepts).
void check_tiles_join(const models::VaeConfig& cfg, const models::VaeTiling& tiling);

// The VAE tiling the options ask for (none without --vae-tiling).
std::optional<models::VaeTiling> vae_tiling(const RunOptions& o);

// Where the transformer's and T5's block weights live for this run (RunOptions::weights): as the option says,
// or with "auto" as the memory plan for this run on this device decides (pipeline/memory_plan.hpp).
struct WeightResidencies {
  models::WeightResidency transformer = models::WeightResidency::resident, text_encoder = models::WeightResidency::resident;
};
// run.json's "weights": the option, and where each component's blocks really lived (the loaded model's own
// residency; "not loaded" when the run took its latent from the cache).
struct WeightsUsed {
  std::optional<models::WeightResidency> transformer, text_encoder;
  nlohmann::json record(const std::string& requested) const;
};
WeightResidencies weight_residencies(const vk::Context& ctx, const RunOptions& o);

// Loads the transformer with the options' LoRA (if any) applied, its block weights resident or streamed.
std::unique_ptr<models::CogVideoXTransformer> load_transformer(vk::Context& ctx, const RunOptions& o,
                                                               models::WeightResidency residency);

struct InversionResult {
  Tensor eps;  // ε_inv at t0, diffusion layout
  bool from_cache = false;
  std::filesystem::path cache_file;  // empty without the cache
};

// What names the clip of a run on files in the caches' keys: the video's and the depth's fingerprints and the
// trajectory. A clip in memory is named by its bytes' fingerprint instead (pipeline/clip_input.hpp).
std::vector<std::string> file_input_key(const RunOptions& o);

// The inversion cache's key: a hash of everything ε_inv depends on and nothing else; `input` names the clip
// (the three-argument form: the files o names).
std::string inversion_cache_key(const RunOptions& o, const JobPlan& jp, int frames);
std::string inversion_cache_key(const RunOptions& o, const JobPlan& jp, int frames, const std::vector<std::string>& input);

// DDIM inversion of x0_mean up to the plan's t0 with the "" prompt embedding `text_empty`, through the on-disk
// cache (keyed by everything ε_inv depends on, LoRA and tiling included; `input` names the clip, by default the
// files o names).
InversionResult invert_render(vk::Context& ctx, models::CogVideoXTransformer& transformer, const RunOptions& o,
                              const JobPlan& jp, int frames, const EncodedRender& enc, const Tensor& text_empty,
                              StageTracker& stages);
InversionResult invert_render(vk::Context& ctx, models::CogVideoXTransformer& transformer, const RunOptions& o,
                              const JobPlan& jp, int frames, const std::vector<std::string>& input,
                              const EncodedRender& enc, const Tensor& text_empty, StageTracker& stages);

// The sampled latent on disk, in the inversion cache's folder (latent-<key>.npy and its .json metadata),
// written before the decode: a run that fails or is interrupted in the decode is re-run straight to it.
std::string latent_cache_key(const RunOptions& o, const JobPlan& jp, int frames, bool dynamic_cfg);
std::string latent_cache_key(const RunOptions& o, const JobPlan& jp, int frames, bool dynamic_cfg,
                             const std::vector<std::string>& input);

struct CachedLatent {
  Tensor latent;       // what the decode takes (the final x0 prediction, diffusion layout)
  nlohmann::json meta; // what the run.json of a run reusing it needs (see run_pipeline.cpp)
};

class LatentCache {
 public:
  LatentCache(const RunOptions& o, std::string key);
  // nullopt when absent; a damaged entry is removed and `rejected` says why.
  std::optional<CachedLatent> load(vk::Context& ctx, const Shape& shape, std::string* rejected) const;
  // Empty when the entry was written; else why not (nothing of it is left behind).
  [[nodiscard]] std::string store(vk::Context& ctx, const Tensor& latent, const nlohmann::json& meta) const;
  std::filesystem::path file() const;
  std::filesystem::path meta_file() const;
  const std::string& key() const { return key_; }

 private:
  InversionCache cache_;
  std::string key_;
};

}  // namespace dvs
