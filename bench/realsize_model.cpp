#include "realsize_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "dvs/error.hpp"
#include "spec/model_folder.hpp"
#include "spec/model_schema.hpp"
#include "pipeline/memory_plan.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_random.hpp"
#include "vk/device_limits.hpp"
#include "vk/limit_profiles.hpp"
#include "vk/memory.hpp"

namespace dvs::bench::realsize {

Scale scale_from_env() {
  const char* env = std::getenv("DVS_REALSIZE_SCALE");
  const std::string v = env ? env : "full";
  Scale s;
  s.name = v;
  const char* profile = std::getenv("DVS_REALSIZE_PROFILE");
  s.profile = profile ? profile : "";
  if (!s.profile.empty()) vk::limit_profile(s.profile);  // an unknown name is an error naming the profiles
  const char* weights = std::getenv("DVS_REALSIZE_WEIGHTS");
  const std::string w = weights ? weights : s.profile.empty() ? "resident" : "stream";
  if (w != "resident" && w != "stream") throw Error("DVS_REALSIZE_WEIGHTS must be resident or stream, got '" + w + "'");
  s.weights = w == "stream" ? models::WeightResidency::stream : models::WeightResidency::resident;
  if (v == "full") return s;
  if (v != "small") throw Error("DVS_REALSIZE_SCALE must be 'full' or 'small', got '" + v + "'");
  // Same widths, heads, text length; few tokens / pixels. Odd-ish sizes on purpose.
  s.t5_vocab = 8000;  // 8000 x 4096 bf16 = 62.5 MiB, inside one binding until the token gather splits
  s.latent_frames = 2;
  s.latent_height = 6;
  s.latent_width = 10;
  s.image_height = 72;  // 2 x 2 tiles whose edge tiles still survive three 2x downsamplings
  s.image_width = 96;
  s.tile_height = 48;
  s.tile_width = 64;
  s.sampled_tokens = 5;
  return s;
}

nlohmann::json t5_config(const Scale& s) {
  nlohmann::json c = pipeline::builtin_plan_model("cogvideox-5b-i2v").text_encoder;
  c["num_layers"] = s.t5_layers;
  c["vocab_size"] = s.t5_vocab;
  return c;
}

nlohmann::json transformer_config(const Scale& s) {
  nlohmann::json c = pipeline::builtin_plan_model("cogvideox-5b-i2v").transformer;
  c["num_layers"] = s.transformer_layers;
  c["sample_height"] = s.latent_height;
  c["sample_width"] = s.latent_width;
  c["sample_frames"] = (s.latent_frames - 1) * c["temporal_compression_ratio"].get<int64_t>() + 1;
  return c;
}

nlohmann::json vae_config(const Scale& s) {
  nlohmann::json c = pipeline::builtin_plan_model("cogvideox-5b-i2v").vae;
  c["sample_height"] = s.image_height;
  c["sample_width"] = s.image_width;
  return c;
}

namespace {

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

// (mean, std) of a tensor's random init (see random_weights).
std::pair<float, float> init_of(const std::string& name, const Shape& shape) {
  if (name == "shared.weight" || name.find("relative_attention_bias") != std::string::npos ||
      name.find("pos_embedding") != std::string::npos)
    return {0.0f, 0.5f};
  if (ends_with(name, ".bias")) return {0.0f, 0.02f};
  if (shape.size() == 1) return {1.0f, 0.05f};  // LayerNorm / GroupNorm / RMSNorm scales
  const int64_t fan_in = shape_numel(shape) / shape[0];
  return {0.0f, float(1.0 / std::sqrt(double(fan_in)))};
}

}  // namespace

models::ComponentWeights random_weights(vk::Context& ctx, const nlohmann::json& config, const std::string& origin,
                                        uint64_t seed) {
  const Schema schema = schema_for(config_class_name(config), config, origin);
  std::map<std::string, Tensor> tensors;
  // Chunks: f32 draw and bf16 destination both inside one binding (and one 1-D grid).
  const int64_t cap = std::min<int64_t>(int64_t(1) << 22, int64_t(ops::max_groups_1d(ctx.caps())) * 64);
  uint32_t stream = 0;
  for (const TensorSpec& spec : schema.tensors) {
    if (spec.optional) continue;
    const auto [mean, std] = init_of(spec.name, spec.shape);
    Tensor t = Tensor::empty(ctx, spec.shape, DType::bf16, origin + " " + spec.name);
    const int64_t n = t.numel();
    const int64_t chunk = ops::rows_per_chunk(ctx.caps(), "random weights", {{4, 16}, {2, 8}}, std::min(n, cap));
    Tensor draw = Tensor::empty(ctx, {chunk}, DType::f32, "random weight draw");
    const uint32_t this_stream = stream++;
    // One submission per tensor (the recorder orders each chunk's draw after the previous chunk's cast read it): the
    // H200 run of 2026-11-29 spent 50 s making T5's weights chunk by chunk, one submission each.
    ops::run_now(ctx, [&](vk::Recorder& rec) {
      ops::for_each_chunk(n, chunk, [&](int64_t first, int64_t count) {
        const Tensor d = Tensor::on(draw.buffer().sub(0, VkDeviceSize(count) * 4), {count}, DType::f32);
        ops::random_normal(rec, d, {seed, this_stream, uint64_t(first)}, mean, std);
        // The whole tensor when it is one chunk (keeps an odd-length bf16 tensor's slack for cast).
        const Tensor dst = count == n ? t.reshape({n})
                                      : Tensor::on(t.buffer().sub(VkDeviceSize(first) * 2, VkDeviceSize(count) * 2),
                                                   {count}, DType::bf16);
        ops::cast(rec, d, dst);
      });
    });
    tensors.emplace(spec.name, std::move(t));
  }
  return models::ComponentWeights(ctx, config, std::move(tensors), origin);
}

const std::vector<float>& HostWeights::operator[](const std::string& name) {
  if (auto it = cache_.find(name); it != cache_.end()) return it->second;
  if (all_) throw Error("realsize: no host copy of weight '" + name + "'");
  return cache_.emplace(name, w_.get(name).download(ctx_).to_f32()).first->second;
}

void HostWeights::load_all() {
  for (const std::string& name : w_.names()) (*this)[name];
  all_ = true;
}

std::string apply_profile(vk::Context& ctx, const Scale& s) {
  if (s.profile.empty()) return "the device's own limits";
  const vk::LimitProfile& p = vk::limit_profile(s.profile);
  vk::LimitOverrides o;
  o.binding = p.binding, o.texels = p.texels, o.alloc = p.alloc, o.groups = p.groups[0], o.memory = p.heap;
  ctx.override_limits(o);
  const vk::DeviceCaps& c = ctx.caps();
  return "profile " + p.name + ": bindings " + vk::format_bytes(c.max_storage_buffer_range) + ", texel views " +
         std::to_string(c.max_texel_buffer_elements) + ", allocations " + vk::format_bytes(c.max_memory_allocation_size) +
         ", device memory " + vk::format_bytes(c.memory_budget.bytes) + (c.forced_limits.memory ? "" : " (the device has less)");
}

}  // namespace dvs::bench::realsize
