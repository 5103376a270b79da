// Device memory of a whole dvs run, planned from the model's config.json files alone (no weights read, no
// device): weight bytes per component, the peak of each model stage, the peak of the run and, given a budget,
// the VAE spatial tiling that fits. Each model call's figure comes from beside its model
// (models/cogvideox/cogvideox_memory.hpp, models/vda/vda_memory.hpp); this file adds them up into the run's
// phases. The report a user reads is pipeline/memory_plan_report.cpp.
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/host_tensor.hpp"
#include "geometry/splat_memory.hpp"
#include "spec/vda_config.hpp"
#include "models/call_memory.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/vae_tiling.hpp"
#include "pipeline/weight_stream_plan.hpp"
#include "vk/device_info.hpp"

namespace dvs::pipeline {

// A component's largest weight tensor: each weight is uploaded as one allocation.
struct LargestWeight {
  uint64_t bytes = 0;
  std::string what;  // "weight 'name' [shape] BF16"
};

// The three configs a plan needs, and the stored bytes of each component's weights when known.
struct PlanModel {
  std::string source;  // the folder, or the built-in name
  nlohmann::json transformer, vae, text_encoder;
  // Per component: stored bytes read from the safetensors headers (nullopt: no weights present; the plan
  // then counts the config's tensors at `assumed_dtype_bytes` each).
  std::optional<uint64_t> transformer_stored, vae_stored, text_encoder_stored;
  std::optional<LargestWeight> transformer_largest, vae_largest, text_encoder_largest;  // from the headers too
  std::map<std::string, uint64_t> transformer_tensors, text_encoder_tensors;  // bytes per tensor, from the headers
  int assumed_dtype_bytes = 2;  // bf16, the real model's storage
};

// Built-in configurations: "cogvideox-5b-i2v" (THUDM/CogVideoX-5b-I2V's config.json files, bf16 weights).
std::vector<std::string> builtin_model_names();
bool is_builtin_model(std::string_view name);
PlanModel builtin_plan_model(std::string_view name);
// <dir>/{transformer,vae,text_encoder}/config.json, plus the safetensors headers when present (headers only).
PlanModel plan_model_from_folder(const std::filesystem::path& dir);

// The device limits a plan is checked against (a real device's caps, or a profile of vk/limit_profiles.hpp).
struct PlanLimits {
  std::string source;                   // "device 0: llvmpipe ...", "profile nvidia: ..."
  uint64_t binding = 0;                 // maxStorageBufferRange, bytes
  uint64_t texels = 0;                  // maxTexelBufferElements
  uint64_t alloc = 0;                   // maxMemoryAllocationSize, bytes
  uint32_t groups = 0;                  // maxComputeWorkGroupCount (x)
  // Weight streaming's figures where known (a profile's typical values; vk/limit_profiles.hpp): host -> device
  // bytes/s, the device's peak flop/s, whether it has a transfer-only queue family.
  std::optional<double> upload_rate, peak_flops;
  std::optional<bool> transfer_queue;
};

struct PlanRequest {
  int64_t frames = 49, height = 480, width = 720;  // pixels
  int prompts = 2;                                 // T5 batch: negative + positive prompt
  std::optional<uint64_t> budget;                  // bytes
  uint64_t alignment = 256;                        // the device allocator's (dvs info; 256 covers common GPUs)
  std::optional<PlanLimits> limits;                // checked when given: a setting runs only within them
  // --depth-model: the depth estimate runs first, alone (its own context, freed before the models load).
  std::optional<VdaConfig> depth_model;
  int depth_input_size = 518;
  int64_t depth_frame_height = 0, depth_frame_width = 0;  // the video's frames; 0 = the clip size
  // The render stage (stage 1-2, before any model loads): the splat renderer's z-buffer mode (--points).
  bool hard_points = false;
  // The VAE tiling a run was given (dvs run --vae-tile): the plan weighs it alone against untiled
  // (tilings = [untiled, this]) instead of offering its own tile sizes.
  std::optional<models::VaeTiling> tiling;
  // Where the transformer's and T5's block weights live (dvs run --weights): auto streams a component only where
  // its phase does not fit the budget with its weights resident.
  WeightsChoice weights = WeightsChoice::automatic;
  int stream_slots = 2;
  std::optional<double> upload_rate;  // host -> device bytes/s (dvs info --bench-upload); else the limits'
};

struct ComponentWeightBytes {
  std::string name;      // "transformer", "vae", "text_encoder"
  uint64_t params = 0;   // from the config's tensor list (tied/optional tensors not counted)
  uint64_t bytes = 0;    // stored bytes
  bool from_headers = false;
  LargestWeight largest;  // from the headers, else the config's largest tensor x the assumed dtype
};

// One model call's memory (models/call_memory.hpp: working set, the tensors around it, its largest tensor).
using models::StageMemory;

struct TilingOption {
  bool tiled = false;
  models::VaeTiling tiling;          // diffusers' enable_tiling() settings (tile sizes resolved)
  models::TilePlan encode, decode;   // as the VAE derives them
  int64_t tiles = 1;                 // tiles per frame (encode)
  StageMemory vae_encode, vae_decode;
  uint64_t run_peak = 0;             // the largest phase of the run with this tiling (see plan_memory)
  std::string blocker;               // why this setting cannot run within the budget and limits ("" = it runs)
  bool fixed = false;                // the blocker is a stage no VAE tiling changes (weights, T5, transformer)
};

struct MemoryPlan {
  PlanRequest request;
  std::string source;
  int64_t latent_frames = 0, latent_height = 0, latent_width = 0, text_len = 0;
  std::vector<ComponentWeightBytes> weights;
  uint64_t weights_total = 0;
  std::vector<StageMemory> stages;   // untiled ("depth_estimate" first with --depth-model, then "render")
  geometry::SplatFootprint render;   // the render stage's chunk and buffers (its problem on the limits, if any)
  uint64_t depth_weights = 0;        // the depth model's, resident during its stage only
  uint64_t carried = 0;              // tensors kept across stages (text embeddings, latents)
  uint64_t run_peak = 0;             // untiled
  std::vector<WeightStreamPlan> streams;  // "transformer", "text_encoder": streamed or not, and what it costs
  std::vector<TilingOption> tilings; // [0] untiled, then smaller and smaller tiles
  int chosen = -1;                   // index into tilings when a budget is given and something fits
  bool checked() const { return request.budget || request.limits; }
  std::vector<std::string> notes;
};

// Throws dvs::Error for bad sizes (frames not 4k+1, height/width not multiples of the latent patch).
MemoryPlan plan_memory(const PlanModel& model, const PlanRequest& request);
// The plan's residency for `component` ("transformer", "text_encoder"): what dvs run --weights auto loads.
models::WeightResidency planned_residency(const MemoryPlan& plan, const std::string& component);

// The stage figures on their own (tests compare them with live allocations).
// `caps` as for the transformer below; a d_kv that is not a multiple of 4 adds the attention's padded copies
// (ops_attention.hpp) in any case.
StageMemory plan_t5_stage(const nlohmann::json& t5_config, bool embedding_16bit, uint64_t alignment, int64_t batch,
                          int64_t len, const vk::DeviceCaps* caps = nullptr);
// `caps`: the limits the call runs under (the attention's split scratch depends on them); none: unsplit.
StageMemory plan_transformer_stage(const nlohmann::json& config, uint64_t alignment, int64_t batch, int64_t latent_frames,
                                   int64_t latent_height, int64_t latent_width, int64_t text_len, int weight_bytes = 2,
                                   const vk::DeviceCaps* caps = nullptr);
StageMemory plan_vae_encode_stage(const nlohmann::json& config, uint64_t alignment, const Shape& video);
StageMemory plan_vae_decode_stage(const nlohmann::json& config, uint64_t alignment, const Shape& z);

// The VAE tile sizes the plan offers: `dvs run --vae-tile HxW` accepts each (multiples of 8 whose tiles join,
// checked with run's own check_tiles_join), about sample size / 2, / 4, ... while the latent tile is ≥ 4 x 4.
std::vector<std::pair<int64_t, int64_t>> plan_tile_sizes(const models::VaeConfig& vae);

// "24GiB", "80GB", "1.5 GiB", "512MiB", "1000000" (bytes). Throws dvs::Error naming `option` otherwise.
uint64_t parse_byte_size(const std::string& text, const std::string& option = "--budget");

// Bytes as the plan prints them (two decimals, unlike vk::format_bytes): "1.50 GiB", "12.00 MiB", "3.00 KiB", "512 B".
std::string format_plan_bytes(uint64_t bytes);

// The plan as a user reads it (`dvs plan`), and its --json form (pipeline/memory_plan_report.cpp).
std::string format_plan_table(const MemoryPlan& plan);
nlohmann::json plan_to_json(const MemoryPlan& plan);

}  // namespace dvs::pipeline
