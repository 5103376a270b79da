#include "pipeline/memory_plan.hpp"

#include <algorithm>
#include <cctype>
#include <functional>

#include "io/option_names.hpp"
#include "dvs/error.hpp"
#include "models/cogvideox/cogvideox_memory.hpp"
#include "models/vda/vda_memory.hpp"
#include "models/vda/vda_model.hpp"
#include "models/vda/vda_preprocess.hpp"
#include "pipeline/job_stages.hpp"
#include "spec/cogvideox_config.hpp"
#include "spec/model_folder.hpp"
#include "spec/model_schema.hpp"
#include "spec/t5_config.hpp"

namespace dvs::pipeline {

using models::allocation_bytes;
using nlohmann::json;

namespace {

uint64_t schema_params(const Schema& s) {
  uint64_t n = 0;
  for (const auto& t : s.tensors)
    if (!t.optional) n += uint64_t(shape_numel(t.shape));
  return n;
}

void require_4k1(int64_t frames) {
  if (frames < 1 || (frames - 1) % 4 != 0)
    throw Error(option_name("MemoryPlanRequest::frames") + " must be 4k+1 (1, 5, 9, ..., 49), got " +
                    std::to_string(frames) + ": the VAE compresses time by 4 after the first frame",
                ErrorKind::invalid_argument);
}

std::optional<uint64_t> stored_bytes(const std::filesystem::path& dir) {
  if (!WeightSet::dir_has_weights(dir)) return std::nullopt;
  return WeightSet::open_dir(dir).total_bytes();  // headers only: the data is mapped, never read
}

std::string weight_text(const std::string& name, const Shape& shape, const std::string& dtype) {
  return "weight '" + name + "' [" + shape_str(shape) + "] " + dtype;
}

// Bytes per tensor from the headers (weight streaming packs them block by block); empty without weights.
std::map<std::string, uint64_t> stored_tensors(const std::filesystem::path& dir) {
  std::map<std::string, uint64_t> out;
  if (!WeightSet::dir_has_weights(dir)) return out;
  const WeightSet weights = WeightSet::open_dir(dir);  // kept: entries() points into it
  for (const auto& [name, ref] : weights.entries()) out[name] = ref.info->nbytes();
  return out;
}

// Multiply-adds x 2 of one CogVideoX block at `batch` x `seq` tokens: q, k, v, out (4·D²) and the FFN (8·D²) per
// token, and the attention's two products (2·S·D per token).
double transformer_block_flops(const CogVideoXTransformerConfig& c, int64_t batch, int64_t seq) {
  const double D = double(c.dim()), S = double(seq), B = double(batch);
  return 2.0 * B * S * (12.0 * D * D) + 4.0 * B * S * S * D;
}

// The same for a T5 layer: q, k, v, o (4·D·I), the FFN (2 or 3 · D·F) and the attention (2·L·I).
double t5_layer_flops(const T5EncoderConfig& c, int64_t batch, int64_t len) {
  const double D = double(c.d_model), I = double(c.inner()), F = double(c.d_ff), L = double(len), B = double(batch);
  return 2.0 * B * L * (4.0 * D * I + (c.gated ? 3.0 : 2.0) * D * F) + 4.0 * B * L * L * I;
}

std::optional<LargestWeight> stored_largest(const std::filesystem::path& dir) {
  if (!WeightSet::dir_has_weights(dir)) return std::nullopt;
  LargestWeight l;
  const WeightSet weights = WeightSet::open_dir(dir);
  for (const auto& [name, ref] : weights.entries())
    if (ref.info->nbytes() > l.bytes) l = {ref.info->nbytes(), weight_text(name, ref.info->shape, ref.info->dtype_name)};
  return l;
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
  CogVideoXConfigFiles real = cogvideox_5b_i2v_config_files();
  m.transformer = std::move(real.transformer);
  m.vae = std::move(real.vae);
  m.text_encoder = std::move(real.text_encoder);
  m.assumed_dtype_bytes = 2;
  return m;
}

PlanModel plan_model_from_folder(const std::filesystem::path& dir) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec))
    throw Error(dir.string() + ": no such model folder (give " + option_name("MemoryPlanRequest::model") +
                " a folder laid out like THUDM/CogVideoX-5b-I2V, or cogvideox-5b-i2v for the built-in real configuration)");
  PlanModel m;
  m.source = dir.string();
  const char* hint = "the model folder needs transformer/, vae/ and text_encoder/ with their config.json";
  m.transformer = read_json_file(dir / "transformer" / "config.json", hint);
  m.vae = read_json_file(dir / "vae" / "config.json", hint);
  m.text_encoder = read_json_file(dir / "text_encoder" / "config.json", hint);
  m.transformer_stored = stored_bytes(dir / "transformer");
  m.vae_stored = stored_bytes(dir / "vae");
  m.text_encoder_stored = stored_bytes(dir / "text_encoder");
  m.transformer_largest = stored_largest(dir / "transformer");
  m.vae_largest = stored_largest(dir / "vae");
  m.text_encoder_largest = stored_largest(dir / "text_encoder");
  m.transformer_tensors = stored_tensors(dir / "transformer");
  m.text_encoder_tensors = stored_tensors(dir / "text_encoder");
  // T5's activations depend on whether the embedding table is 16-bit; with weights, the header says.
  if (WeightSet::dir_has_weights(dir / "text_encoder")) {
    const WeightSet w = WeightSet::open_dir(dir / "text_encoder");
    if (const WeightRef* r = w.find("shared.weight")) m.assumed_dtype_bytes = int(r->info->elem_size);
  }
  return m;
}

// ---- stages ---------------------------------------------------------------------------------------------------

// The per-model figures live beside the models (models/cogvideox/cogvideox_memory.hpp).
StageMemory plan_t5_stage(const json& t5_config, bool embedding_16bit, uint64_t alignment, int64_t batch, int64_t len,
                          const vk::DeviceCaps* caps) {
  return models::t5_call_memory(t5_config, embedding_16bit, alignment, batch, len, caps);
}

StageMemory plan_transformer_stage(const json& config, uint64_t alignment, int64_t batch, int64_t F, int64_t H, int64_t W,
                                   int64_t L, int weight_bytes, const vk::DeviceCaps* caps) {
  return models::transformer_call_memory(config, alignment, batch, F, H, W, L, weight_bytes, caps);
}

StageMemory plan_vae_encode_stage(const json& config, uint64_t alignment, const Shape& video) {
  return models::vae_encode_call_memory(config, alignment, video, true);
}

StageMemory plan_vae_decode_stage(const json& config, uint64_t alignment, const Shape& z) {
  return models::vae_decode_call_memory(config, alignment, z);
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
  const auto tcfg = CogVideoXTransformerConfig::from_json(model.transformer, "transformer config");
  const VaeConfig vcfg = VaeConfig::from_json(model.vae);
  const auto t5cfg = T5EncoderConfig::from_json(model.text_encoder, "text_encoder config");  // errors name the config

  const int64_t r = vcfg.spatial_ratio(), cell = r * tcfg.patch_size;
  if (req.height < cell || req.width < cell || req.height % cell || req.width % cell)
    throw Error(option_name("MemoryPlanRequest::height") + " and " + option_name("MemoryPlanRequest::width") +
                    " must be positive multiples of " + std::to_string(cell) + " (VAE ratio " + std::to_string(r) +
                    " x patch " + std::to_string(tcfg.patch_size) + "), got " + std::to_string(req.height) + "x" +
                    std::to_string(req.width),
                ErrorKind::invalid_argument);
  if (vcfg.latent_channels * 2 != tcfg.in_channels || vcfg.latent_channels != tcfg.out_channels)
    plan.notes.push_back("the VAE's latent_channels (" + std::to_string(vcfg.latent_channels) +
                         ") do not match the transformer's in/out channels (" + std::to_string(tcfg.in_channels) + "/" +
                         std::to_string(tcfg.out_channels) + "); dvs run would refuse this model");
  plan.latent_frames = (req.frames - 1) / vcfg.temporal_compression_ratio + 1;
  plan.latent_height = req.height / r;
  plan.latent_width = req.width / r;
  plan.text_len = tcfg.max_text_seq_length;
  // A transformer with a learned positional table takes one size only: the plan of another never runs.
  std::string size_blocker;
  if (tcfg.learned_pos && (plan.latent_height != tcfg.sample_height || plan.latent_width != tcfg.sample_width))
    size_blocker = "the transformer's learned positional table fixes the size to " + std::to_string(tcfg.sample_height * r) +
                   "x" + std::to_string(tcfg.sample_width * r) + "; it rejects " + std::to_string(req.height) + "x" +
                   std::to_string(req.width);

  // Weights.
  auto component = [&](const char* name, const Schema& s, const std::optional<uint64_t>& stored,
                       const std::optional<LargestWeight>& largest) {
    ComponentWeightBytes c;
    c.name = name;
    c.params = schema_params(s);
    c.from_headers = stored.has_value();
    c.bytes = stored ? *stored : c.params * uint64_t(model.assumed_dtype_bytes);
    if (largest) {
      c.largest = *largest;
    } else {
      const int eb = model.assumed_dtype_bytes;
      for (const auto& t : s.tensors)
        if (uint64_t(shape_numel(t.shape)) * uint64_t(eb) > c.largest.bytes)
          c.largest = {uint64_t(shape_numel(t.shape)) * uint64_t(eb), weight_text(t.name, t.shape, eb == 2 ? "BF16" : "F32")};
    }
    plan.weights_total += c.bytes;
    plan.weights.push_back(c);
  };
  component("transformer", tr_schema, model.transformer_stored, model.transformer_largest);
  component("vae", vae_schema, model.vae_stored, model.vae_largest);
  component("text_encoder", t5_schema, model.text_encoder_stored, model.text_encoder_largest);
  // Each weight is one allocation, resident while its model's calls run: a call's largest tensor counts it.
  auto with_weights = [&](StageMemory st, const char* component_name) {
    for (const auto& w : plan.weights)
      if (w.name == component_name) st.consider_buffer(w.largest.bytes, w.largest.what);
    return st;
  };

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
  // The depth estimate's frames (their size, the window's at the end).
  const int64_t depth_fh = req.depth_frame_height > 0 ? req.depth_frame_height : req.height;
  const int64_t depth_fw = req.depth_frame_width > 0 ? req.depth_frame_width : req.width;
  if (req.depth_model) {
    const VdaConfig& dc = *req.depth_model;
    const int64_t fh = depth_fh, fw = depth_fw;
    const VdaInputSize in = vda_input_size(fh, fw, req.depth_input_size, dc.patch_size);
    const VdaMemory vm = plan_vda_memory(dc, dc.infer_len, in.height, in.width, fh, fw, VdaModel::kHeadMicroBatch, req.alignment);
    StageMemory d;
    d.name = "depth_estimate";
    d.what = "Video-Depth-Anything " + dc.name + ", windows of " + std::to_string(dc.infer_len) + " frames at " +
             std::to_string(in.height) + "x" + std::to_string(in.width) + " for " + std::to_string(fh) + "x" +
             std::to_string(fw) + " frames (weights " + format_plan_bytes(vm.weights) + ", peak in " + vm.peak_phase + ")";
    d.working = vm.activations;
    d.largest_bytes = vm.largest_tensor;
    d.largest_elements = int64_t(vm.largest_tensor / 4);
    d.largest_what = vm.largest_what;
    plan.stages.push_back(d);
    plan.depth_weights = vm.weights;
  }
  // The render: the splat renderer's chunk and buffers, on the limits when given (render_job.cpp renders first,
  // in the run's context, and frees them before the VAE loads).
  geometry::SplatLimits splat_limits;
  if (req.limits)
    splat_limits = {req.limits->binding, req.limits->alloc, req.limits->groups, req.limits->groups, req.limits->source};
  plan.render = geometry::splat_footprint(req.frames, req.height, req.width, req.hard_points, false, splat_limits, req.alignment);
  {
    StageMemory rs;
    rs.name = "render";
    rs.what = "splat renderer, " + std::to_string(plan.render.chunk_frames) + " of " + std::to_string(req.frames) +
              " frames at a time";
    rs.io = plan.render.total;
    rs.consider_buffer(plan.render.largest.bytes, plan.render.largest.what);
    plan.stages.push_back(rs);
  }
  // A call whose ops find no split under the limits (ErrorKind::device) is a verdict of the plan, not an error.
  auto beyond_limits = [&](const std::string& name, const std::function<StageMemory()>& plan_stage) {
    try {
      return plan_stage();
    } catch (const Error& e) {
      if (e.kind() != ErrorKind::device) throw;
      StageMemory st;
      st.name = name;
      st.problem = name + ": " + e.what();
      st.what = "CANNOT RUN: " + std::string(e.what());
      return st;
    }
  };
  plan.stages.push_back(with_weights(beyond_limits("t5_encode", [&] {
    return plan_t5_stage(model.text_encoder, emb16, req.alignment, req.prompts, L, limits);
  }), "text_encoder"));
  StageMemory cfg2 = with_weights(beyond_limits("transformer_cfg", [&] {
    return plan_transformer_stage(model.transformer, req.alignment, 2, Fl, Hl, Wl, L, model.assumed_dtype_bytes, limits);
  }), "transformer");
  cfg2.name = "transformer_cfg";
  cfg2.what += " (CFG: negative + positive)";
  StageMemory inv = with_weights(beyond_limits("transformer_inversion", [&] {
    return plan_transformer_stage(model.transformer, req.alignment, 1, Fl, Hl, Wl, L, model.assumed_dtype_bytes, limits);
  }), "transformer");
  inv.name = "transformer_inversion";
  inv.what += " (inversion)";
  plan.stages.push_back(cfg2);
  plan.stages.push_back(inv);
  const Shape video{1, vcfg.in_channels, req.frames, req.height, req.width};
  const Shape z{1, vcfg.latent_channels, Fl, Hl, Wl};
  const StageMemory enc = with_weights(plan_vae_encode_stage(model.vae, req.alignment, video), "vae");
  const StageMemory dec = with_weights(plan_vae_decode_stage(model.vae, req.alignment, z), "vae");
  plan.stages.push_back(enc);
  plan.stages.push_back(dec);

  // Kept across stages: the prompt embeddings (CFG pair + inversion "") and four latents (x0, image latent,
  // the inverted noise, the initial noise).
  plan.carried = allocation_bytes({req.prompts, L, tcfg.text_embed_dim}, req.alignment) +
                 allocation_bytes({1, L, tcfg.text_embed_dim}, req.alignment) +
                 4 * allocation_bytes({Fl, vcfg.latent_channels, Hl, Wl}, req.alignment);
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
  // Weight streaming: each component's block weights resident, or in slots (auto: where resident does not fit).
  WeightStreamPlan trs = plan_weight_stream("transformer", tr_schema, "transformer_blocks.", model.transformer_tensors,
                                            model.assumed_dtype_bytes, "", req.alignment, req.stream_slots);
  WeightStreamPlan t5s = plan_weight_stream("text_encoder", t5_schema, "encoder.block.", model.text_encoder_tensors,
                                            model.assumed_dtype_bytes,
                                            "encoder.block.0.layer.0.SelfAttention.relative_attention_bias.weight",
                                            req.alignment, req.stream_slots);
  trs.calls = "per sampling or inversion step";
  t5s.calls = "once per run";
  const std::optional<double> rate = req.upload_rate ? req.upload_rate : req.limits ? req.limits->upload_rate : std::nullopt;
  const std::optional<double> peak = req.limits ? req.limits->peak_flops : std::nullopt;
  const std::optional<bool> beside = req.limits ? req.limits->transfer_queue : std::nullopt;
  // The less favourable transformer call (the inversion's batch of 1 computes half as long per upload).
  time_weight_stream(trs, transformer_block_flops(tcfg, 1, L + plan.latent_frames * (Hl / tcfg.patch_size) * (Wl / tcfg.patch_size)),
                     rate, peak, beside);
  time_weight_stream(t5s, t5_layer_flops(t5cfg, req.prompts, L), rate, peak, beside);
  const uint64_t t5_call = stage_of("t5_encode");
  const uint64_t tr_call = std::max(stage_of("transformer_cfg"), stage_of("transformer_inversion"));
  auto choose = [&](WeightStreamPlan& st, uint64_t resident_weights, uint64_t call) {
    st.streamed = req.weights == WeightsChoice::stream ||
                  (req.weights == WeightsChoice::automatic && req.budget && st.blocks > 0 &&
                   plan.carried + vae_w + resident_weights + call > *req.budget);
    return vae_w + (st.streamed ? st.device_bytes() : resident_weights) + call;
  };
  const uint64_t text_phase = choose(t5s, weights_of("text_encoder"), t5_call);
  const uint64_t transformer_phase = choose(trs, weights_of("transformer"), tr_call);
  plan.streams = {trs, t5s};
  auto run_peak = [&](const StageMemory& e, const StageMemory& d) {
    // The depth estimate runs alone, before anything else is loaded.
    return std::max({plan.depth_weights + stage_of("depth_estimate"), stage_of("render"),
                     plan.carried + std::max({text_phase, transformer_phase, vae_w + e.total(), vae_w + d.total()})});
  };
  plan.run_peak = run_peak(enc, dec);

  // Tiling options: untiled, then diffusers' default tile (half the VAE's sample size) and halvings of it, as long
  // as the tile is smaller than the clip and its latent tile at least 4 x 4; or, when the run names its tiling,
  // that one alone. Each tiled call's figures are the VAE's own (CogVideoXVae::*_tiled_footprint).
  TilingOption untiled;
  untiled.vae_encode = enc;
  untiled.vae_decode = dec;
  untiled.run_peak = plan.run_peak;
  plan.tilings.push_back(untiled);
  auto tiled_option = [&](const models::VaeTiling& t) {
    TilingOption o;
    o.tiled = true;
    o.tiling = t;
    o.encode = models::TilePlan::for_encode(vcfg, t);
    o.decode = models::TilePlan::for_decode(vcfg, t);
    o.tiles = o.encode.stride_h > 0 && o.encode.stride_w > 0
                  ? ((req.height + o.encode.stride_h - 1) / o.encode.stride_h) * ((req.width + o.encode.stride_w - 1) / o.encode.stride_w)
                  : 0;
    o.vae_encode = with_weights(models::vae_encode_tiled_call_memory(model.vae, req.alignment, video, t), "vae");
    o.vae_decode = with_weights(models::vae_decode_tiled_call_memory(model.vae, req.alignment, z, t), "vae");
    o.run_peak = run_peak(o.vae_encode, o.vae_decode);
    return o;
  };
  if (req.tiling) {
    models::VaeTiling t = *req.tiling;
    if (t.tile_sample_min_height <= 0) t.tile_sample_min_height = vcfg.sample_height / 2;
    if (t.tile_sample_min_width <= 0) t.tile_sample_min_width = vcfg.sample_width / 2;
    plan.tilings.push_back(tiled_option(t));
  } else {
    for (const auto& [th, tw] : plan_tile_sizes(vcfg)) {
      models::VaeTiling t;
      t.tile_sample_min_height = int(th);
      t.tile_sample_min_width = int(tw);
      const auto pe = models::TilePlan::for_encode(vcfg, t), pd = models::TilePlan::for_decode(vcfg, t);
      if (!(req.width > pe.tile_in_w || req.height > pe.tile_in_h)) continue;  // no tiling at this size
      if (pe.stride_h <= 0 || pe.stride_w <= 0 || pd.stride_h <= 0 || pd.stride_w <= 0) break;
      plan.tilings.push_back(tiled_option(t));
    }
  }

  // A setting runs when its whole-run peak is within the budget and every tensor of every stage fits one
  // allocation (ops split a tensor over bindings and texel views; an allocation cannot be split).
  auto too_big = [&](const StageMemory& st) -> std::string {
    if (!st.problem.empty()) return st.problem;
    if (!req.limits || st.largest_bytes <= req.limits->alloc) return "";
    return st.name + "'s " + st.largest_what + " (" + format_plan_bytes(st.largest_bytes) + ") exceeds maxMemoryAllocationSize " +
           format_plan_bytes(req.limits->alloc) + " of " + req.limits->source;
  };
  std::string fixed_blocker = size_blocker;  // what no tiling helps: the size, the render, a non-VAE stage
  if (fixed_blocker.empty()) fixed_blocker = plan.render.problem;
  if (fixed_blocker.empty() && req.depth_model)  // it runs alone: what helps is a smaller network input
    fixed_blocker = vda_fit_problem(*req.depth_model, depth_fh, depth_fw, req.depth_input_size,
                                    req.limits ? req.limits->alloc : 0, req.budget, req.alignment,
                                    req.limits ? req.limits->source : "", "--depth-input-size");
  for (const auto& st : plan.stages)
    if (st.name != "vae_encode" && st.name != "vae_decode" && fixed_blocker.empty()) fixed_blocker = too_big(st);
  for (auto& t : plan.tilings) {
    t.blocker = fixed_blocker;
    t.fixed = !fixed_blocker.empty();
    if (t.blocker.empty()) t.blocker = too_big(t.vae_encode);
    if (t.blocker.empty()) t.blocker = too_big(t.vae_decode);
    if (t.blocker.empty() && req.budget && t.run_peak > *req.budget)
      t.blocker = "the run's peak " + format_plan_bytes(t.run_peak) + " exceeds the budget " + format_plan_bytes(*req.budget);
  }
  if (!plan.checked() && !size_blocker.empty()) plan.notes.push_back(size_blocker);
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
        plan.notes.push_back("nothing fits in " + format_plan_bytes(*req.budget) + ": the " +
                             (transformer_phase >= text_phase
                                  ? std::string("transformer phase (VAE + transformer weights") +
                                        (trs.streamed ? " streamed" : "") + " and its call)"
                                  : std::string("text phase (VAE + T5 weights") + (t5s.streamed ? " streamed" : "") +
                                        " and its call)") +
                             " already needs " + format_plan_bytes(floor_bytes) + " with any VAE tiling; use a device " +
                             "with more memory or fewer frames" +
                             (tcfg.learned_pos ? std::string(" (this model's size is fixed by its learned positional table)")
                                               : std::string(" / a smaller size")));
      else
        plan.notes.push_back("nothing runs: even the smallest VAE tile tried: " + plan.tilings.back().blocker);
    } else if (plan.chosen < 0) {
      plan.notes.push_back("nothing runs: even the smallest VAE tile tried: " + plan.tilings.back().blocker);
    }
  }
  return plan;
}

models::WeightResidency planned_residency(const MemoryPlan& plan, const std::string& component) {
  for (const auto& st : plan.streams)
    if (st.component == component)
      return st.streamed ? models::WeightResidency::stream : models::WeightResidency::resident;
  throw Error("internal: the memory plan has no component '" + component + "'");
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

}  // namespace dvs::pipeline
