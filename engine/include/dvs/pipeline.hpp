// The whole dynamic-view-synthesis job (docs/design.md §1): render the input along a new camera path, encode the
// render, invert it, initialise the noise (SLM + adaptive K-RNR) and sample the new view. What `dvs run`
// and `dvs demo` execute.
#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "dvs/render.hpp"
#include "dvs/api.hpp"

namespace dvs {

struct RunOptions {
  RenderJob render;                 // video, depth, trajectory, frames, size, out_dir, device, ...
  std::filesystem::path model;      // Hugging Face folder laid out like THUDM/CogVideoX-5b-I2V
  std::string prompt;
  std::string negative_prompt;      // empty: "" (paper) / the official fixed text (official preset)
  std::string preset = "paper";     // "paper" or "official": the defaults below follow it unless set
  int steps = 0;                    // 0 = preset default (paper 50, official 30)
  double strength = 0;              // 0 = preset default (paper 0.95, official 0.98)
  int inversion_steps = 0;          // 0 = preset default (30)
  double k = 10;
  double delta = 0;                 // 0 = preset default (paper 3, official 2)
  double guidance = 6.0;
  // The official position-wise dynamic CFG (docs/design.md §6.7): occluded latents (the official
  // mask V < 1) get a per-step scale from `guidance`, fully visible ones `preservation_scale`. Unset = the
  // preset's choice (official on, paper off: constant `guidance` everywhere).
  std::optional<bool> dynamic_cfg;
  double preservation_scale = 1.0;  // dynamic CFG only; the official config's 1.0 = the cond prediction
  uint64_t seed = 42;
  std::filesystem::path cache_dir;  // the cache folder, as --cache-dir (dvs/cache.hpp); empty = $DVS_CACHE_DIR, else ~/.cache/dvs
  bool use_cache = true;
  std::filesystem::path lora;       // LoRA adapter (.safetensors, diffusers/PEFT layout) on the transformer; empty: none
  double lora_scale = 1.0;
  bool vae_tiling = false;          // tiled VAE encode/decode (diffusers' enable_tiling): less device memory
  int vae_tile_height = 0, vae_tile_width = 0;  // tile in pixels; 0 = half the VAE's sample size (diffusers)
  // The transformer's and T5's block weights: "resident" on the device, "stream" from host memory through a
  // few device slots behind the compute, or "auto" (the memory plan's choice for this run on this device:
  // streamed only where resident does not fit). Results are byte-identical either way.
  std::string weights = "auto";
};

struct StageTime {
  std::string stage;
  double seconds = 0;
};

struct RunReport {
  std::vector<StageTime> stages;
  bool inversion_from_cache = false;
  std::filesystem::path output_mp4, render_mp4, mask_mp4, comparison_mp4, run_json;
  uint64_t peak_device_bytes = 0;
};

// Progress events: stage name, step (1-based) and total steps of that stage (0 when not stepped).
using ProgressFn = std::function<void(const std::string& stage, int step, int total, const std::string& note)>;
// Polled at stage boundaries and before every diffusion step; true stops the job with dvs::Cancelled.
using CancelFn = std::function<bool()>;

// Any failure (dvs::Error naming the stage, or dvs::Cancelled) leaves no output of this run in out_dir.
DVS_API RunReport run_pipeline(const RunOptions& options, const ProgressFn& progress = {}, const CancelFn& cancelled = {});

struct InversionReport {
  std::vector<StageTime> stages;
  bool from_cache = false;
  std::filesystem::path eps_inv_npy;  // out_dir/eps_inv.npy: ε_inv [latent frames, C, h, w] f32
  std::filesystem::path cache_file;   // where `dvs run` finds it (empty with use_cache = false)
  std::vector<int64_t> shape;
  int t0 = 0;
};

// Stages 1–5 of run_pipeline (render, VAE encode, DDIM inversion up to t0) with the same options, so a
// later run_pipeline with those options (any prompt, guidance, k or seed) takes ε_inv from the cache.
DVS_API InversionReport run_inversion(const RunOptions& options, const ProgressFn& progress = {}, const CancelFn& cancelled = {});

// T5 embeddings of `prompt` exactly as the pipeline computes them ([1, max_text_seq_length, d_model] f32),
// written to `out_npy`; returns the shape.
DVS_API std::vector<int64_t> encode_prompt(const std::filesystem::path& model, const std::string& prompt,
                                           const std::filesystem::path& out_npy, const std::string& device = "");

// Writes a synthetic RGB-D clip (video + exact metric depth) and a tiny random model into `dir`, and
// returns options that run the whole pipeline on them in a few minutes on a CPU (lavapipe).
DVS_API RunOptions prepare_demo(const std::filesystem::path& dir);

}  // namespace dvs
