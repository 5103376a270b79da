#include "pipeline/memory_plan.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "dvs/error.hpp"
#include "spec/model_folder.hpp"
#include "spec/model_schema.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/vda/vda_memory.hpp"
#include "models/vda/vda_model.hpp"
#include "models/vda/vda_preprocess.hpp"
#include "pipeline/job_stages.hpp"
#include "tensor/ops_attention.hpp"

namespace dvs::pipeline {

using nlohmann::json;

namespace {

uint64_t align_up(uint64_t bytes, uint64_t alignment) { return (bytes + alignment - 1) / alignment * alignment; }

// Device bytes of one tensor as the allocator reserves them.
uint64_t tensor_bytes(const Shape& shape, uint64_t alignment, uint64_t elem = 4) {
  return align_up(std::max<uint64_t>(uint64_t(shape_numel(shape)) * elem, 1), alignment);
}

// THUDM/CogVideoX-5b-I2V, the config.json files as published (keys diffusers/transformers read).
json real_transformer_config() {
  return {{"_class_name", "CogVideoXTransformer3DModel"}, {"activation_fn", "gelu-approximate"},
          {"attention_bias", true}, {"attention_head_dim", 64}, {"dropout", 0.0}, {"flip_sin_to_cos", true},
          {"freq_shift", 0}, {"in_channels", 32}, {"max_text_seq_length", 226}, {"norm_elementwise_affine", true},
          {"norm_eps", 1e-5}, {"num_attention_heads", 48}, {"num_layers", 42}, {"out_channels", 16},
          {"patch_size", 2}, {"sample_frames", 49}, {"sample_height", 60}, {"sample_width", 90},
          {"spatial_interpolation_scale", 1.875}, {"temporal_compression_ratio", 4},
          {"temporal_interpolation_scale", 1.0}, {"text_embed_dim", 4096}, {"time_embed_dim", 512},
          {"timestep_activation_fn", "silu"}, {"use_learned_positional_embeddings", true},
          {"use_rotary_positional_embeddings", true}};
}

json real_vae_config() {
  return {{"_class_name", "AutoencoderKLCogVideoX"}, {"act_fn", "silu"}, {"block_out_channels", {128, 256, 256, 512}},
          {"down_block_types", std::vector<std::string>(4, "CogVideoXDownBlock3D")}, {"force_upcast", true},
          {"in_channels", 3}, {"latent_channels", 16}, {"layers_per_block", 3}, {"norm_eps", 1e-6},
          {"norm_num_groups", 32}, {"out_channels", 3}, {"sample_height", 480}, {"sample_width", 720},
          {"scaling_factor", 0.7}, {"temporal_compression_ratio", 4},
          {"up_block_types", std::vector<std::string>(4, "CogVideoXUpBlock3D")}, {"use_post_quant_conv", false},
          {"use_quant_conv", false}};
}

json real_t5_config() {
  return {{"architectures", {"T5EncoderModel"}}, {"d_ff", 10240}, {"d_kv", 64}, {"d_model", 4096},
          {"dense_act_fn", "gelu_new"}, {"feed_forward_proj", "gated-gelu"}, {"is_gated_act", true},
          {"layer_norm_epsilon", 1e-6}, {"model_type", "t5"}, {"num_heads", 64}, {"num_layers", 24},
          {"relative_attention_max_distance", 128}, {"relative_attention_num_buckets", 32},
          {"tie_word_embeddings", false}, {"torch_dtype", "bfloat16"}, {"vocab_size", 32128}};
}

uint64_t schema_params(const Schema& s) {
  uint64_t n = 0;
  for (const auto& t : s.tensors)
    if (!t.optional) n += uint64_t(shape_numel(t.shape));
  return n;
}

int64_t ceil_halvings(int64_t x, int64_t times) {
  for (int64_t i = 0; i < times; ++i) x = (x + 1) / 2;
  return x;
}

std::string shape_text(const Shape& s) { return "[" + shape_str(s) + "]"; }

// Keeps the larger of the stage's largest tensor and `shape` (elem bytes each).
void consider(StageMemory& m, const Shape& shape, uint64_t elem, const std::string& what) {
  const uint64_t bytes = uint64_t(shape_numel(shape)) * elem;
  if (bytes <= m.largest_bytes) return;
  m.largest_bytes = bytes;
  m.largest_elements = shape_numel(shape);
  m.largest_what = what + " " + shape_text(shape) + (elem == 4 ? " f32" : elem == 2 ? " bf16" : "");
}

int64_t max_batch(const std::vector<std::pair<int64_t, int64_t>>& batches) {
  int64_t b = 1;
  for (const auto& [start, end] : batches) b = std::max(b, end - start);
  return b;
}

// The largest activation of a VAE pass over `frames` frames (a frame batch plus the causal conv's 2 cached
// frames) at h x w pixels: each level's channels (block ℓ reads c[ℓ-1] and works at c[ℓ]) at its resolution,
// with the conv's 1-pixel padding. An upper figure at the levels that also compress time.
void consider_vae_levels(StageMemory& m, const models::VaeConfig& cfg, int64_t frames, int64_t h, int64_t w,
                         const std::string& what) {
  const auto& c = cfg.block_out_channels;
  for (size_t l = 0; l < c.size(); ++l) {
    const int64_t ch = std::max(c[l], c[l == 0 ? 0 : l - 1]);
    consider(m, {1, ch, frames + 2, ceil_halvings(h, int64_t(l)) + 2, ceil_halvings(w, int64_t(l)) + 2}, 4,
             what + " level " + std::to_string(l) + " activation");
  }
}

// A VAE encode call of `video` (encode_moments, plus the posterior when `posterior`): the device peak above the
// weights. One frame batch: the input, the batch's working set and the result copied out of it (the VAE copies
// a result whose pool buffer is larger; an exact fit is not copied, so this is an upper figure), then the
// posterior beside the moments. Several batches: the bands copied out of the input and the concatenation of the
// per-batch results come on top. The VAE's dry run counts its buffers unpadded; the allocator pads small ones
// (GroupNorm scratch) to its alignment, a few alignments per call at most.
StageMemory vae_encode_call(const json& config, uint64_t alignment, const Shape& video, bool posterior) {
  const models::VaeConfig cfg = models::VaeConfig::from_json(config);
  const int64_t levels = int64_t(cfg.block_out_channels.size()) - 1;
  const int64_t frames = video[2];
  const int64_t lf = frames == 1 ? 1 : (frames - 1) / cfg.temporal_compression_ratio + 1;
  const Shape moments{video[0], 2 * cfg.latent_channels, lf, ceil_halvings(video[3], levels), ceil_halvings(video[4], levels)};
  Shape half = moments;
  half[1] = cfg.latent_channels;
  StageMemory m;
  m.name = "vae_encode";
  m.what = "VAE encode of " + shape_text(video);
  m.working = models::CogVideoXVae::encode_working_bytes(config, video);
  const uint64_t in = tensor_bytes(video, alignment), mom = tensor_bytes(moments, alignment);
  const uint64_t post = posterior ? 2 * tensor_bytes(half, alignment) : 0;
  uint64_t total;
  if (models::CogVideoXVae::frame_batches(frames, 8).size() == 1) total = in + std::max(m.working + mom, mom + post);
  else total = 2 * in + m.working + 2 * mom + post;
  m.io = total - m.working;
  consider(m, video, 4, "input clip");
  consider(m, moments, 4, "moments");
  consider_vae_levels(m, cfg, max_batch(models::CogVideoXVae::frame_batches(frames, 8)), video[3], video[4], "encoder");
  return m;
}

// A VAE decode call of z: the input, the working set and the frames copied out of it, and (several latent
// batches) the bands and the concatenation, as for encode.
StageMemory vae_decode_call(const json& config, uint64_t alignment, const Shape& z) {
  const models::VaeConfig cfg = models::VaeConfig::from_json(config);
  const int64_t r = cfg.spatial_ratio();
  const Shape frames{z[0], cfg.out_channels, (z[2] - 1) * cfg.temporal_compression_ratio + 1, z[3] * r, z[4] * r};
  StageMemory m;
  m.name = "vae_decode";
  m.what = "VAE decode of " + shape_text(z);
  m.working = models::CogVideoXVae::decode_working_bytes(config, z);
  const uint64_t in = tensor_bytes(z, alignment), out = tensor_bytes(frames, alignment);
  uint64_t total;
  if (models::CogVideoXVae::frame_batches(z[2], 2).size() == 1) total = in + m.working + out;
  else total = 2 * in + m.working + 2 * out;
  m.io = total - m.working;
  consider(m, frames, 4, "decoded frames");
  const int64_t lb = max_batch(models::CogVideoXVae::frame_batches(z[2], 2));
  consider_vae_levels(m, cfg, lb * cfg.temporal_compression_ratio, frames[3], frames[4], "decoder");
  return m;
}

void require_4k1(int64_t frames) {
  if (frames < 1 || (frames - 1) % 4 != 0)
    throw Error("--frames must be 4k+1 (1, 5, 9, ..., 49), got " + std::to_string(frames) +
                ": the VAE compresses time by 4 after the first frame");
}

std::optional<uint64_t> stored_bytes(const std::filesystem::path& dir) {
  if (!WeightSet::dir_has_weights(dir)) return std::nullopt;
  return WeightSet::open_dir(dir).total_bytes();  // headers only: the data is mapped, never read
}

std::string gib(uint64_t bytes) {
  char buf[64];
  if (bytes >= (uint64_t(1) << 30)) std::snprintf(buf, sizeof buf, "%.2f GiB", double(bytes) / double(1ull << 30));
  else if (bytes >= (uint64_t(1) << 20)) std::snprintf(buf, sizeof buf, "%.2f MiB", double(bytes) / double(1ull << 20));
  else if (bytes >= 1024) std::snprintf(buf, sizeof buf, "%.2f KiB", double(bytes) / 1024.0);
  else std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(bytes));
  return buf;
}

json stage_json(const StageMemory& s) {
  return {{"name", s.name}, {"what", s.what}, {"working_bytes", s.working}, {"io_bytes", s.io}, {"total_bytes", s.total()}};
}


int64_t pieces(uint64_t amount, uint64_t limit) { return limit == 0 ? 1 : int64_t((amount + limit - 1) / limit); }

// One stage's largest tensor against the limits: how many bindings / texel views ops split it into, and
// whether it fits one allocation (it must: the stage cannot run otherwise).
std::string limits_verdict(const StageMemory& s, const PlanLimits& l) {
  std::string v = "largest tensor " + gib(s.largest_bytes) + " (" + s.largest_what + "): ";
  const int64_t b = pieces(s.largest_bytes, l.binding), t = pieces(uint64_t(s.largest_elements), l.texels);
  v += b > 1 ? "split into " + std::to_string(b) + " bindings" : std::string("one binding");
  v += ", " + std::to_string(s.largest_elements) + " texels: " +
       (t > 1 ? "split into " + std::to_string(t) + " texel views" : std::string("one texel view"));
  v += s.largest_bytes > l.alloc ? ", allocation OVER maxMemoryAllocationSize: cannot run" : ", allocation fits";
  return v;
}

json limits_json(const StageMemory& s, const PlanLimits& l) {
  return {{"largest_tensor_bytes", s.largest_bytes}, {"largest_tensor", s.largest_what},
          {"largest_texel_view", s.largest_elements}, {"bindings", pieces(s.largest_bytes, l.binding)},
          {"texel_views", pieces(uint64_t(s.largest_elements), l.texels)}, {"allocation_fits", s.largest_bytes <= l.alloc}};
}

}  // namespace

// ---- models ---------------------------------------------------------------------------------------------------

std::vector<std::string> builtin_model_names() { return {"cogvideox-5b-i2v"}; }

bool is_builtin_model(std::string_view name) {
  std::string lower(name);
  for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
  return lower == "cogvideox-5b-i2v" || lower == "thudm/cogvideox-5b-i2v";
}

PlanModel builtin_plan_model(std::string_view name) {
  if (!is_builtin_model(name))
    throw Error("no built-in model named '" + std::string(name) + "' (built-in: cogvideox-5b-i2v)");
  PlanModel m;
  m.source = "cogvideox-5b-i2v (built-in THUDM/CogVideoX-5b-I2V config, bf16 weights)";
  m.transformer = real_transformer_config();
  m.vae = real_vae_config();
  m.text_encoder = real_t5_config();
  m.assumed_dtype_bytes = 2;
  return m;
}

PlanModel plan_model_from_folder(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec))
    throw Error(dir.string() + ": no such model folder (give --model DIR laid out like THUDM/CogVideoX-5b-I2V, or "
                "--model cogvideox-5b-i2v for the built-in real configuration)");
  PlanModel m;
  m.source = dir.string();
  const char* hint = "the model folder needs transformer/, vae/ and text_encoder/ with their config.json";
  m.transformer = read_json_file(dir / "transformer" / "config.json", hint);
  m.vae = read_json_file(dir / "vae" / "config.json", hint);
  m.text_encoder = read_json_file(dir / "text_encoder" / "config.json", hint);
  m.transformer_stored = stored_bytes(dir / "transformer");
  m.vae_stored = stored_bytes(dir / "vae");
  m.text_encoder_stored = stored_bytes(dir / "text_encoder");
  // T5's activations depend on whether the embedding table is 16-bit; with weights, the header says.
  if (WeightSet::dir_has_weights(dir / "text_encoder")) {
    const WeightSet w = WeightSet::open_dir(dir / "text_encoder");
    if (const WeightRef* r = w.find("shared.weight")) m.assumed_dtype_bytes = int(r->info->elem_size);
  }
  return m;
}

// ---- stages ---------------------------------------------------------------------------------------------------

StageMemory plan_t5_stage(const json& t5_config, bool embedding_16bit, uint64_t alignment, int64_t batch, int64_t len,
                          const vk::DeviceCaps* caps) {
  const auto cfg = models::T5EncoderConfig::from_json(t5_config);
  StageMemory m;
  m.name = "t5_encode";
  m.what = "T5 encode of " + std::to_string(batch) + " prompt(s) x " + std::to_string(len) + " tokens";
  m.working = models::T5Encoder::arena_bytes(cfg, embedding_16bit, alignment, batch, len);
  m.io = tensor_bytes({batch, len}, alignment) /* ids, i32 */ + tensor_bytes({cfg.num_heads, len, len}, alignment) /* bias */ +
         tensor_bytes({batch, len, cfg.d_model}, alignment) /* last_hidden_state */;
  // Attention scratch of the recording: a d_kv that is not a multiple of 4 is copied head-padded (under any
  // limits); split calls (under `caps`) repack K/V and carry running state.
  if (caps || cfg.d_kv % 4 != 0) {
    vk::DeviceCaps unlimited;  // no limits named: nothing splits, only the padded copies
    unlimited.max_storage_buffer_range = unlimited.max_texel_buffer_elements = 1ull << 40;
    unlimited.max_memory_allocation_size = 1ull << 50;
    unlimited.min_storage_buffer_offset_alignment = unlimited.min_texel_buffer_offset_alignment = alignment;
    for (uint32_t& g : unlimited.max_workgroup_count) g = UINT32_MAX;
    m.io += ops::attention_split_plan_fused(caps ? *caps : unlimited, {batch, cfg.num_heads, cfg.d_kv, len, len}, true)
                .scratch_bytes;
  }
  consider(m, {cfg.vocab_size, cfg.d_model}, embedding_16bit ? 2 : 4, "token embedding");
  consider(m, {cfg.d_ff, cfg.d_model}, embedding_16bit ? 2 : 4, "FFN weight");
  consider(m, {batch, len, cfg.d_ff}, 4, "FFN activation");
  consider(m, {batch, cfg.num_heads, len, len}, 4, "attention scores");
  return m;
}

StageMemory plan_transformer_stage(const json& config, uint64_t alignment, int64_t batch, int64_t F, int64_t H, int64_t W,
                                   int64_t L, int weight_bytes, const vk::DeviceCaps* caps) {
  const auto cfg = models::CogVideoXTransformerConfig::from_json(config);
  const int64_t p = cfg.patch_size, N = F * (H / p) * (W / p);
  StageMemory m;
  m.name = "transformer";
  m.what = "transformer call, batch " + std::to_string(batch) + " x (" + std::to_string(L) + " + " + std::to_string(N) +
           ") tokens";
  m.working = models::CogVideoXTransformer::arena_bytes(cfg, alignment, batch, F, H, W, L);
  m.io = tensor_bytes({batch, F, cfg.in_channels, H, W}, alignment) + tensor_bytes({batch, L, cfg.text_embed_dim}, alignment) +
         tensor_bytes({batch}, alignment) /* timesteps */ + tensor_bytes({batch, F, cfg.out_channels, H, W}, alignment);
  if (cfg.rotary) m.io += 2 * tensor_bytes({N, cfg.head_dim}, alignment);           // RoPE cos, sin
  if (cfg.learned_pos || !cfg.rotary) m.io += tensor_bytes({L + N, cfg.dim()}, alignment);  // positional table
  // Attention split over bindings: head-major K/V and running-state scratch of the recording.
  if (caps)
    m.io += ops::attention_split_plan_fused(*caps, {batch, cfg.heads, cfg.head_dim, L + N, L + N}).scratch_bytes;
  // diffusers' FeedForward: inner width 4 x dim (12288 for the 5B model).
  consider(m, {cfg.dim(), 4 * cfg.dim()}, uint64_t(weight_bytes), "FFN weight");
  consider(m, {batch, L + N, 3 * cfg.dim()}, 4, "q, k, v");
  consider(m, {batch, L + N, 4 * cfg.dim()}, 4, "FFN activation");
  consider(m, {batch, F, cfg.in_channels, H, W}, 4, "latent input");
  return m;
}

StageMemory plan_vae_encode_stage(const json& config, uint64_t alignment, const Shape& video) {
  return vae_encode_call(config, alignment, video, true);
}

StageMemory plan_vae_decode_stage(const json& config, uint64_t alignment, const Shape& z) {
  return vae_decode_call(config, alignment, z);
}

// ---- the plan -------------------------------------------------------------------------------------------------

MemoryPlan plan_memory(const PlanModel& model, const PlanRequest& req) {
  require_4k1(req.frames);
  if (req.alignment == 0 || (req.alignment & (req.alignment - 1)) != 0) throw Error("memory plan: alignment must be a power of two");
  MemoryPlan plan;
  plan.request = req;
  plan.source = model.source;

  const Schema tr_schema = cogvideox_transformer_schema(model.transformer, "transformer config");
  const Schema vae_schema = cogvideox_vae_schema(model.vae, "vae config");
  const Schema t5_schema = t5_encoder_schema(model.text_encoder, "text_encoder config");
  const auto tcfg = models::CogVideoXTransformerConfig::from_json(model.transformer, "transformer config");
  const models::VaeConfig vcfg = models::VaeConfig::from_json(model.vae);
  const auto t5cfg = models::T5EncoderConfig::from_json(model.text_encoder, "text_encoder config");

  const int64_t r = vcfg.spatial_ratio(), cell = r * tcfg.patch_size;
  if (req.height < cell || req.width < cell || req.height % cell || req.width % cell)
    throw Error("--height and --width must be positive multiples of " + std::to_string(cell) + " (VAE ratio " +
                std::to_string(r) + " x patch " + std::to_string(tcfg.patch_size) + "), got " +
                std::to_string(req.height) + "x" + std::to_string(req.width));
  if (vcfg.latent_channels * 2 != tcfg.in_channels || vcfg.latent_channels != tcfg.out_channels)
    plan.notes.push_back("the VAE's latent_channels (" + std::to_string(vcfg.latent_channels) +
                         ") do not match the transformer's in/out channels (" + std::to_string(tcfg.in_channels) + "/" +
                         std::to_string(tcfg.out_channels) + "); dvs run would refuse this model");
  plan.latent_frames = (req.frames - 1) / vcfg.temporal_compression_ratio + 1;
  plan.latent_height = req.height / r;
  plan.latent_width = req.width / r;
  plan.text_len = tcfg.max_text_seq_length;
  if (tcfg.learned_pos && (plan.latent_height != tcfg.sample_height || plan.latent_width != tcfg.sample_width))
    plan.notes.push_back("the learned positional embedding fixes the size to " + std::to_string(tcfg.sample_height * r) +
                         "x" + std::to_string(tcfg.sample_width * r) + "; the transformer rejects " +
                         std::to_string(req.height) + "x" + std::to_string(req.width));

  // Weights.
  auto component = [&](const char* name, const Schema& s, const std::optional<uint64_t>& stored) {
    ComponentWeightBytes c;
    c.name = name;
    c.params = schema_params(s);
    c.from_headers = stored.has_value();
    c.bytes = stored ? *stored : c.params * uint64_t(model.assumed_dtype_bytes);
    plan.weights_total += c.bytes;
    plan.weights.push_back(c);
  };
  component("transformer", tr_schema, model.transformer_stored);
  component("vae", vae_schema, model.vae_stored);
  component("text_encoder", t5_schema, model.text_encoder_stored);

  // Stages, untiled.
  const int64_t Fl = plan.latent_frames, Hl = plan.latent_height, Wl = plan.latent_width, L = plan.text_len;
  const bool emb16 = model.assumed_dtype_bytes == 2;
  // The limits the calls split under, where the request names them (the attention's scratch follows them).
  std::optional<vk::DeviceCaps> caps;
  if (req.limits) {
    caps.emplace();
    caps->max_storage_buffer_range = req.limits->binding;
    caps->max_texel_buffer_elements = req.limits->texels;
    caps->max_memory_allocation_size = req.limits->alloc;
    for (uint32_t& g : caps->max_workgroup_count) g = req.limits->groups;
    caps->min_storage_buffer_offset_alignment = caps->min_texel_buffer_offset_alignment = req.alignment;
  }
  const vk::DeviceCaps* limits = caps ? &*caps : nullptr;
  if (req.depth_model) {
    const VdaConfig& dc = *req.depth_model;
    const int64_t fh = req.depth_frame_height > 0 ? req.depth_frame_height : req.height;
    const int64_t fw = req.depth_frame_width > 0 ? req.depth_frame_width : req.width;
    const VdaInputSize in = vda_input_size(fh, fw, req.depth_input_size, dc.patch_size);
    const VdaMemory vm = plan_vda_memory(dc, dc.infer_len, in.height, in.width, fh, fw, VdaModel::kHeadMicroBatch, req.alignment);
    StageMemory d;
    d.name = "depth_estimate";
    d.what = "Video-Depth-Anything " + dc.name + ", windows of " + std::to_string(dc.infer_len) + " frames at " +
             std::to_string(in.height) + "x" + std::to_string(in.width) + " for " + std::to_string(fh) + "x" +
             std::to_string(fw) + " frames (weights " + gib(vm.weights) + ", peak in " + vm.peak_phase + ")";
    d.working = vm.activations;
    d.largest_bytes = vm.largest_tensor;
    d.largest_elements = int64_t(vm.largest_tensor / 4);
    d.largest_what = vm.largest_what;
    plan.stages.push_back(d);
    plan.depth_weights = vm.weights;
  }
  plan.stages.push_back(plan_t5_stage(model.text_encoder, emb16, req.alignment, req.prompts, L, limits));
  StageMemory cfg2 =
      plan_transformer_stage(model.transformer, req.alignment, 2, Fl, Hl, Wl, L, model.assumed_dtype_bytes, limits);
  cfg2.name = "transformer_cfg";
  cfg2.what += " (CFG: negative + positive)";
  StageMemory inv =
      plan_transformer_stage(model.transformer, req.alignment, 1, Fl, Hl, Wl, L, model.assumed_dtype_bytes, limits);
  inv.name = "transformer_inversion";
  inv.what += " (inversion)";
  plan.stages.push_back(cfg2);
  plan.stages.push_back(inv);
  const Shape video{1, vcfg.in_channels, req.frames, req.height, req.width};
  const Shape z{1, vcfg.latent_channels, Fl, Hl, Wl};
  const StageMemory enc = plan_vae_encode_stage(model.vae, req.alignment, video);
  const StageMemory dec = plan_vae_decode_stage(model.vae, req.alignment, z);
  plan.stages.push_back(enc);
  plan.stages.push_back(dec);

  // Kept across stages: the prompt embeddings (CFG pair + inversion "") and four latents (x0, image latent,
  // the inverted noise, the initial noise).
  plan.carried = tensor_bytes({req.prompts, L, tcfg.text_embed_dim}, req.alignment) +
                 tensor_bytes({1, L, tcfg.text_embed_dim}, req.alignment) +
                 4 * tensor_bytes({Fl, vcfg.latent_channels, Hl, Wl}, req.alignment);
  // The run's phases (run_pipeline.cpp): the VAE stays loaded throughout; T5 only for the text stage, the
  // transformer only for inversion and sampling. Each phase: the weights resident then + carried + its call.
  auto weights_of = [&](const std::string& name) {
    for (const auto& w : plan.weights)
      if (w.name == name) return w.bytes;
    return uint64_t(0);
  };
  auto stage_of = [&](const std::string& name) {
    for (const auto& st : plan.stages)
      if (st.name == name) return st.total();
    return uint64_t(0);
  };
  const uint64_t vae_w = weights_of("vae");
  const uint64_t text_phase = vae_w + weights_of("text_encoder") + stage_of("t5_encode");
  const uint64_t transformer_phase =
      vae_w + weights_of("transformer") + std::max(stage_of("transformer_cfg"), stage_of("transformer_inversion"));
  auto run_peak = [&](const StageMemory& e, const StageMemory& d) {
    // The depth estimate runs alone, before anything else is loaded.
    return std::max(plan.depth_weights + stage_of("depth_estimate"),
                    plan.carried + std::max({text_phase, transformer_phase, vae_w + e.total(), vae_w + d.total()}));
  };
  plan.run_peak = run_peak(enc, dec);

  // Tiling options: untiled, then diffusers' default tile (half the VAE's sample size) and halvings of it, as long
  // as the tile is smaller than the clip and its latent tile at least 4 x 4.
  TilingOption untiled;
  untiled.vae_encode = enc;
  untiled.vae_decode = dec;
  untiled.run_peak = plan.run_peak;
  plan.tilings.push_back(untiled);
  for (const auto& [th, tw] : plan_tile_sizes(vcfg)) {
    models::VaeTiling t;
    t.tile_sample_min_height = int(th);
    t.tile_sample_min_width = int(tw);
    const auto pe = models::TilePlan::for_encode(vcfg, t), pd = models::TilePlan::for_decode(vcfg, t);
    if (!(req.width > pe.tile_in_w || req.height > pe.tile_in_h)) continue;  // no tiling at this size
    if (pe.stride_h <= 0 || pe.stride_w <= 0 || pd.stride_h <= 0 || pd.stride_w <= 0) break;
    TilingOption o;
    o.tiled = true;
    o.tiling = t;
    o.encode = pe;
    o.decode = pd;
    o.tiles = ((req.height + pe.stride_h - 1) / pe.stride_h) * ((req.width + pe.stride_w - 1) / pe.stride_w);
    // Tiled encode: the clip stays on the device; one tile call at a time; the blended moments come back at the
    // end with the posterior. Tiled decode: the latent stays; one tile call; the blended frames come back.
    const Shape vt{1, vcfg.in_channels, req.frames, std::min(req.height, pe.tile_in_h), std::min(req.width, pe.tile_in_w)};
    const StageMemory te = vae_encode_call(model.vae, req.alignment, vt, false);
    Shape moments = z;
    moments[1] = 2 * vcfg.latent_channels;
    o.vae_encode.name = "vae_encode";
    o.vae_encode.what = "VAE encode of " + shape_text(video) + " in " + std::to_string(o.tiles) + " tiles of " +
                        std::to_string(vt[3]) + "x" + std::to_string(vt[4]);
    o.vae_encode.working = te.working;
    o.vae_encode.io = tensor_bytes(video, req.alignment) +
                      std::max(te.total(), tensor_bytes(moments, req.alignment) + 2 * tensor_bytes(z, req.alignment)) -
                      te.working;
    o.vae_encode.largest_bytes = te.largest_bytes;
    o.vae_encode.largest_elements = te.largest_elements;
    o.vae_encode.largest_what = te.largest_what;
    consider(o.vae_encode, video, 4, "input clip");
    const Shape zt{1, vcfg.latent_channels, Fl, std::min(Hl, pd.tile_in_h), std::min(Wl, pd.tile_in_w)};
    const StageMemory td = vae_decode_call(model.vae, req.alignment, zt);
    o.vae_decode.name = "vae_decode";
    o.vae_decode.what = "VAE decode of " + shape_text(z) + " in tiles of " + std::to_string(zt[3]) + "x" +
                        std::to_string(zt[4]) + " latents";
    o.vae_decode.working = td.working;
    o.vae_decode.io = tensor_bytes(z, req.alignment) +
                      std::max(td.total(), tensor_bytes({1, vcfg.out_channels, req.frames, req.height, req.width}, req.alignment)) -
                      td.working;
    o.vae_decode.largest_bytes = td.largest_bytes;
    o.vae_decode.largest_elements = td.largest_elements;
    o.vae_decode.largest_what = td.largest_what;
    consider(o.vae_decode, {1, vcfg.out_channels, req.frames, req.height, req.width}, 4, "decoded frames");
    o.run_peak = run_peak(o.vae_encode, o.vae_decode);
    plan.tilings.push_back(o);
  }

  // A setting runs when its whole-run peak is within the budget and every tensor of every stage fits one
  // allocation (ops split a tensor over bindings and texel views; an allocation cannot be split).
  auto too_big = [&](const StageMemory& st) -> std::string {
    if (!req.limits || st.largest_bytes <= req.limits->alloc) return "";
    return st.name + "'s " + st.largest_what + " (" + gib(st.largest_bytes) + ") exceeds maxMemoryAllocationSize " +
           gib(req.limits->alloc) + " of " + req.limits->source;
  };
  std::string fixed_blocker;  // a non-VAE stage no tiling helps
  for (const auto& st : plan.stages)
    if (st.name != "vae_encode" && st.name != "vae_decode" && fixed_blocker.empty()) fixed_blocker = too_big(st);
  for (auto& t : plan.tilings) {
    t.blocker = fixed_blocker;
    if (t.blocker.empty()) t.blocker = too_big(t.vae_encode);
    if (t.blocker.empty()) t.blocker = too_big(t.vae_decode);
    if (t.blocker.empty() && req.budget && t.run_peak > *req.budget)
      t.blocker = "the run's peak " + gib(t.run_peak) + " exceeds the budget " + gib(*req.budget);
  }
  if (plan.checked()) {
    for (size_t i = 0; i < plan.tilings.size(); ++i)
      if (plan.tilings[i].blocker.empty()) {
        plan.chosen = int(i);
        break;
      }
    if (plan.chosen < 0 && !fixed_blocker.empty()) {
      plan.notes.push_back("nothing runs: " + fixed_blocker + "; no VAE tiling changes that");
    } else if (plan.chosen < 0 && req.budget) {
      const uint64_t floor_bytes = plan.carried + std::max(text_phase, transformer_phase);
      if (floor_bytes > *req.budget)
        plan.notes.push_back("nothing fits in " + gib(*req.budget) + ": the " +
                             (transformer_phase >= text_phase ? "transformer phase (VAE + transformer weights and its call)"
                                                              : "text phase (VAE + T5 weights and its call)") +
                             " already needs " + gib(floor_bytes) +
                             " with any VAE tiling; use a device with more memory or fewer frames / a smaller size");
      else
        plan.notes.push_back("nothing runs within " + gib(*req.budget) + ": even the smallest VAE tile tried: " +
                             plan.tilings.back().blocker);
    } else if (plan.chosen < 0) {
      plan.notes.push_back("nothing runs: even the smallest VAE tile tried: " + plan.tilings.back().blocker);
    }
  }
  return plan;
}

std::vector<std::pair<int64_t, int64_t>> plan_tile_sizes(const models::VaeConfig& vcfg) {
  const int64_t r = vcfg.spatial_ratio();
  auto accepted = [&](int64_t h, int64_t w) {
    models::VaeTiling t;
    t.tile_sample_min_height = int(h);
    t.tile_sample_min_width = int(w);
    try {
      check_tiles_join(vcfg, t);  // run's own check of --vae-tile
      return true;
    } catch (const Error&) {
      return false;
    }
  };
  // For each target (half the sample size, then halvings), the largest accepted multiples of 8 at or below it.
  std::vector<std::pair<int64_t, int64_t>> out;
  for (int64_t div = 2;; div *= 2) {
    const int64_t target_h = vcfg.sample_height / div / 8 * 8, target_w = vcfg.sample_width / div / 8 * 8;
    if (target_h / r < 4 || target_w / r < 4) break;
    std::optional<std::pair<int64_t, int64_t>> found;
    for (int64_t h = target_h; h / r >= 4 && !found; h -= 8)
      for (int64_t w = target_w; w / r >= 4 && !found; w -= 8)
        if (accepted(h, w)) found = std::make_pair(h, w);
    if (found && std::find(out.begin(), out.end(), *found) == out.end()) out.push_back(*found);
  }
  return out;
}

// ---- sizes ----------------------------------------------------------------------------------------------------

uint64_t parse_byte_size(const std::string& text, const std::string& option) {
  const std::string hint = option + ": '" + text + "' is not a size; use e.g. 24GiB, 80GB, 512MiB or a byte count";
  size_t i = 0;
  while (i < text.size() && (std::isdigit(static_cast<unsigned char>(text[i])) || text[i] == '.')) ++i;
  if (i == 0 || std::count(text.begin(), text.begin() + long(i), '.') > 1) throw Error(hint);
  const double value = std::stod(text.substr(0, i));
  std::string unit = text.substr(i);
  unit.erase(std::remove(unit.begin(), unit.end(), ' '), unit.end());
  for (char& c : unit) c = char(std::tolower(static_cast<unsigned char>(c)));
  double scale;
  if (unit.empty() || unit == "b") scale = 1;
  else if (unit == "k" || unit == "kib") scale = 1024.0;
  else if (unit == "m" || unit == "mib") scale = 1024.0 * 1024.0;
  else if (unit == "g" || unit == "gib") scale = 1024.0 * 1024.0 * 1024.0;
  else if (unit == "t" || unit == "tib") scale = 1024.0 * 1024.0 * 1024.0 * 1024.0;
  else if (unit == "kb") scale = 1e3;
  else if (unit == "mb") scale = 1e6;
  else if (unit == "gb") scale = 1e9;
  else if (unit == "tb") scale = 1e12;
  else throw Error(hint);
  const double bytes = value * scale;
  if (!(bytes >= 1.0) || bytes > 1e18) throw Error(option + ": '" + text + "' must be a positive size below 1 EB");
  return uint64_t(std::llround(bytes));
}

// ---- output ---------------------------------------------------------------------------------------------------

std::string format_plan_table(const MemoryPlan& p) {
  std::ostringstream o;
  char line[256];
  o << "memory plan for " << p.source << "\n";
  o << "  clip " << p.request.frames << " frames x " << p.request.height << "x" << p.request.width << " -> latent "
    << p.latent_frames << "x" << p.latent_height << "x" << p.latent_width << ", " << p.text_len
    << " text tokens; allocations aligned to " << p.request.alignment << " bytes\n\n";
  o << "weights (stored dtype)\n";
  for (const auto& w : p.weights) {
    std::snprintf(line, sizeof line, "  %-14s %14llu params  %12s  (%s)\n", w.name.c_str(),
                  static_cast<unsigned long long>(w.params), gib(w.bytes).c_str(),
                  w.from_headers ? "safetensors headers" : "config x assumed dtype");
    o << line;
  }
  std::snprintf(line, sizeof line, "  %-14s %14s          %12s\n\n", "total", "", gib(p.weights_total).c_str());
  o << line;
  o << "stage peaks above the weights (activations + the call's inputs, outputs and tables)\n";
  for (const auto& s : p.stages) {
    std::snprintf(line, sizeof line, "  %-22s %12s  (activations %s)  %s\n", s.name.c_str(), gib(s.total()).c_str(),
                  gib(s.working).c_str(), s.what.c_str());
    o << line;
  }
  o << "  kept across stages: " << gib(p.carried) << " (prompt embeddings, latents)\n\n";
  if (p.request.limits) {
    const PlanLimits& l = *p.request.limits;
    o << "limits of " << l.source << ": binding (maxStorageBufferRange) " << gib(l.binding)
      << ", texel view (maxTexelBufferElements) " << l.texels << " texels, allocation (maxMemoryAllocationSize) "
      << gib(l.alloc) << ", groups " << l.groups << "\n";
    for (const auto& s : p.stages)
      if (s.name != "vae_encode" && s.name != "vae_decode") o << "  " << s.name << ": " << limits_verdict(s, l) << "\n";
    for (const auto& t : p.tilings) {
      const std::string tag = t.tiled ? " (tiles " + std::to_string(t.tiling.tile_sample_min_height) + "x" +
                                            std::to_string(t.tiling.tile_sample_min_width) + ")"
                                      : std::string(" (untiled)");
      o << "  vae_encode" << tag << ": " << limits_verdict(t.vae_encode, l) << "\n";
      o << "  vae_decode" << tag << ": " << limits_verdict(t.vae_decode, l) << "\n";
    }
    o << "\n";
  }
  o << "whole run (the largest phase: VAE weights + T5 or transformer weights when loaded + kept tensors + that call)\n";
  for (size_t i = 0; i < p.tilings.size(); ++i) {
    const auto& t = p.tilings[i];
    std::string name = t.tiled ? "VAE tiles " + std::to_string(t.tiling.tile_sample_min_height) + "x" +
                                     std::to_string(t.tiling.tile_sample_min_width) + " (" + std::to_string(t.tiles) +
                                     " per frame)"
                               : std::string("VAE untiled");
    std::snprintf(line, sizeof line, "  %-34s peak %12s  (encode %s, decode %s)%s\n", name.c_str(), gib(t.run_peak).c_str(),
                  gib(t.vae_encode.total()).c_str(), gib(t.vae_decode.total()).c_str(),
                  p.checked() && int(i) == p.chosen ? "  <- chosen" : "");
    o << line;
  }
  if (p.checked()) {
    o << "\n";
    if (p.request.budget) o << "budget " << gib(*p.request.budget);
    if (p.request.limits) o << (p.request.budget ? ", " : "") << "limits of " << p.request.limits->source;
    o << ": ";
    if (p.chosen < 0) o << "NOTHING FITS\n";
    else if (p.chosen == 0) o << "runs untiled (peak " << gib(p.tilings[0].run_peak) << "): dvs run without --vae-tiling\n";
    else {
      const auto& t = p.tilings[size_t(p.chosen)];
      o << "needs VAE tiling: dvs run --vae-tile " << t.tiling.tile_sample_min_height << "x" << t.tiling.tile_sample_min_width
        << " (overlap 1/6 x 1/5), peak " << gib(t.run_peak) << "\n";
    }
  }
  for (const auto& n : p.notes) o << "note: " << n << "\n";
  return o.str();
}

json plan_to_json(const MemoryPlan& p) {
  json j;
  j["source"] = p.source;
  j["request"] = {{"frames", p.request.frames}, {"height", p.request.height}, {"width", p.request.width},
                  {"prompts", p.request.prompts}, {"alignment", p.request.alignment}};
  j["request"]["budget_bytes"] = p.request.budget ? json(*p.request.budget) : json(nullptr);
  j["latent"] = {p.latent_frames, p.latent_height, p.latent_width};
  j["text_len"] = p.text_len;
  j["weights"] = json::array();
  for (const auto& w : p.weights)
    j["weights"].push_back({{"name", w.name}, {"params", w.params}, {"bytes", w.bytes},
                            {"basis", w.from_headers ? "safetensors_headers" : "config"}});
  j["weights_total_bytes"] = p.weights_total;
  j["stages"] = json::array();
  for (const auto& s : p.stages) {
    j["stages"].push_back(stage_json(s));
    if (p.request.limits) j["stages"].back()["limits"] = limits_json(s, *p.request.limits);
  }
  j["carried_bytes"] = p.carried;
  j["run_peak_bytes"] = p.run_peak;
  j["tilings"] = json::array();
  for (const auto& t : p.tilings) {
    json e = {{"tiled", t.tiled}, {"run_peak_bytes", t.run_peak}, {"vae_encode", stage_json(t.vae_encode)},
              {"vae_decode", stage_json(t.vae_decode)}};
    if (p.request.limits) {
      e["vae_encode"]["limits"] = limits_json(t.vae_encode, *p.request.limits);
      e["vae_decode"]["limits"] = limits_json(t.vae_decode, *p.request.limits);
    }
    e["runs"] = t.blocker.empty();
    if (!t.blocker.empty()) e["blocker"] = t.blocker;
    if (t.tiled) {
      e["tile_sample_min_height"] = t.tiling.tile_sample_min_height;
      e["tile_sample_min_width"] = t.tiling.tile_sample_min_width;
      e["tiles_per_frame"] = t.tiles;
    }
    j["tilings"].push_back(e);
  }
  if (p.request.limits) {
    const PlanLimits& l = *p.request.limits;
    j["limits"] = {{"source", l.source}, {"binding_bytes", l.binding}, {"texels", l.texels}, {"alloc_bytes", l.alloc},
                   {"groups", l.groups}};
  }
  if (p.checked()) {
    json c = {{"fits", p.chosen >= 0}};
    if (p.chosen >= 0) {
      const auto& t = p.tilings[size_t(p.chosen)];
      c["tiled"] = t.tiled;
      c["run_peak_bytes"] = t.run_peak;
      if (t.tiled) {
        c["tile_sample_min_height"] = t.tiling.tile_sample_min_height;
        c["tile_sample_min_width"] = t.tiling.tile_sample_min_width;
      }
    }
    j["choice"] = c;
  } else {
    j["choice"] = nullptr;
  }
  j["notes"] = p.notes;
  return j;
}

}  // namespace dvs::pipeline
