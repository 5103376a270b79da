#include "spec/cogvideox_config.hpp"

#include <cmath>
#include <string>

#include "dvs/error.hpp"
#include "spec/config_values.hpp"

namespace dvs {

CogVideoXTransformerConfig CogVideoXTransformerConfig::from_json(const nlohmann::json& c, std::string_view origin) {
  const ConfigValues v(c, origin);
  CogVideoXTransformerConfig r;
  r.heads = v.integer_or_default("num_attention_heads", 30, 1);
  r.head_dim = v.integer_or_default("attention_head_dim", 64, 1);
  r.in_channels = v.integer_or_default("in_channels", 16, 1);
  r.out_channels = v.integer_or_default("out_channels", 16, 1);
  r.time_embed_dim = v.integer_or_default("time_embed_dim", 512, 1);
  r.text_embed_dim = v.integer_or_default("text_embed_dim", 4096, 1);
  r.num_layers = v.integer_or_default("num_layers", 30, 0);
  r.patch_size = v.integer_or_default("patch_size", 2, 1);
  r.max_text_seq_length = v.integer_or_default("max_text_seq_length", 226, 0);
  r.sample_width = v.integer_or_default("sample_width", 90, 1);
  r.sample_height = v.integer_or_default("sample_height", 60, 1);
  r.sample_frames = v.integer_or_default("sample_frames", 49, 1);
  r.temporal_compression_ratio = v.integer_or_default("temporal_compression_ratio", 4, 1);
  r.flip_sin_to_cos = v.boolean_or_default("flip_sin_to_cos", true);
  r.freq_shift = v.number_or_default("freq_shift", r.freq_shift);
  r.norm_eps = v.number_or_default("norm_eps", r.norm_eps);
  r.spatial_interpolation_scale = v.number_or_default("spatial_interpolation_scale", r.spatial_interpolation_scale);
  r.temporal_interpolation_scale = v.number_or_default("temporal_interpolation_scale", r.temporal_interpolation_scale);
  r.norm_affine = v.boolean_or_default("norm_elementwise_affine", true);
  r.attention_bias = v.boolean_or_default("attention_bias", true);
  r.rotary = v.boolean_or_default("use_rotary_positional_embeddings", false);
  r.learned_pos = v.boolean_or_default("use_learned_positional_embeddings", false);
  const auto unsupported = [&](const std::string& what) {
    throw Error(std::string(origin) + ": " + what + " is not supported by this port (CogVideoX 1.0 5B/5B-I2V layout)");
  };
  if (c.contains("patch_size_t") && !c["patch_size_t"].is_null()) unsupported("patch_size_t (CogVideoX 1.5)");
  if (c.contains("ofs_embed_dim") && !c["ofs_embed_dim"].is_null() && c["ofs_embed_dim"] != 0)
    unsupported("ofs_embed_dim (CogVideoX 1.5)");
  if (!r.rotary) unsupported("use_rotary_positional_embeddings = false (CogVideoX-2B sincos embedding)");
  if (v.string("activation_fn", "gelu-approximate") != "gelu-approximate") unsupported("activation_fn other than gelu-approximate");
  if (v.string("timestep_activation_fn", "silu") != "silu") unsupported("timestep_activation_fn other than silu");
  if (r.head_dim % 16 != 0) unsupported("attention_head_dim not a multiple of 16 (3D RoPE split)");
  return r;
}

VaeConfig VaeConfig::from_json(const nlohmann::json& j) {
  // Every value's type is checked (ConfigValues), so a malformed config is an error naming the key.
  const ConfigValues v(j, "vae config");
  v.require_object();
  VaeConfig c;
  auto integer = [&](const char* key, int64_t def) { return j.contains(key) && !j[key].is_null() ? v.integer(key, def, 1) : def; };
  c.in_channels = integer("in_channels", 3);
  c.out_channels = integer("out_channels", 3);
  c.latent_channels = integer("latent_channels", 16);
  c.block_out_channels = v.integers("block_out_channels", {128, 256, 256, 512}, 1);
  if (c.block_out_channels.size() > 16)  // one level per halving of the frame (spatial_ratio shifts by it)
    v.fail("block_out_channels", "has " + std::to_string(c.block_out_channels.size()) + " levels; at most 16");
  c.layers_per_block = integer("layers_per_block", 3);
  c.norm_num_groups = integer("norm_num_groups", 32);
  c.norm_eps = v.number_or_default("norm_eps", c.norm_eps);
  c.temporal_compression_ratio = integer("temporal_compression_ratio", 4);
  if (j.contains("scaling_factor") && !j["scaling_factor"].is_null()) {
    if (!j["scaling_factor"].is_number()) v.fail("scaling_factor", "must be a number, got " + j["scaling_factor"].dump());
    c.scaling_factor = j["scaling_factor"].get<double>();
  }
  c.sample_height = integer("sample_height", 480);
  c.sample_width = integer("sample_width", 720);
  c.use_quant_conv = v.boolean_or_default("use_quant_conv", false);
  c.use_post_quant_conv = v.boolean_or_default("use_post_quant_conv", false);
  return c;
}

int64_t VaeConfig::temporal_levels() const {
  // int(np.log2(temporal_compression_ratio))
  return int64_t(std::floor(std::log2(double(temporal_compression_ratio)) + 1e-9));
}

CogVideoXConfigFiles cogvideox_5b_i2v_config_files() {
  CogVideoXConfigFiles f;
  f.transformer = {{"_class_name", "CogVideoXTransformer3DModel"}, {"activation_fn", "gelu-approximate"},
      {"attention_bias", true}, {"attention_head_dim", 64}, {"dropout", 0.0}, {"flip_sin_to_cos", true},
      {"freq_shift", 0}, {"in_channels", 32}, {"max_text_seq_length", 226}, {"norm_elementwise_affine", true},
      {"norm_eps", 1e-5}, {"num_attention_heads", 48}, {"num_layers", 42}, {"out_channels", 16},
      {"patch_size", 2}, {"sample_frames", 49}, {"sample_height", 60}, {"sample_width", 90},
      {"spatial_interpolation_scale", 1.875}, {"temporal_compression_ratio", 4},
      {"temporal_interpolation_scale", 1.0}, {"text_embed_dim", 4096}, {"time_embed_dim", 512},
      {"timestep_activation_fn", "silu"}, {"use_learned_positional_embeddings", true},
      {"use_rotary_positional_embeddings", true}};
  f.vae = {{"_class_name", "AutoencoderKLCogVideoX"}, {"act_fn", "silu"}, {"block_out_channels", {128, 256, 256, 512}},
      {"down_block_types", std::vector<std::string>(4, "CogVideoXDownBlock3D")}, {"force_upcast", true},
      {"in_channels", 3}, {"latent_channels", 16}, {"layers_per_block", 3}, {"norm_eps", 1e-6},
      {"norm_num_groups", 32}, {"out_channels", 3}, {"sample_height", 480}, {"sample_width", 720},
      {"scaling_factor", 0.7}, {"temporal_compression_ratio", 4},
      {"up_block_types", std::vector<std::string>(4, "CogVideoXUpBlock3D")}, {"use_post_quant_conv", false},
      {"use_quant_conv", false}};
  f.text_encoder = {{"architectures", {"T5EncoderModel"}}, {"d_ff", 10240}, {"d_kv", 64}, {"d_model", 4096},
      {"dense_act_fn", "gelu_new"}, {"feed_forward_proj", "gated-gelu"}, {"is_gated_act", true},
      {"layer_norm_epsilon", 1e-6}, {"model_type", "t5"}, {"num_heads", 64}, {"num_layers", 24},
      {"relative_attention_max_distance", 128}, {"relative_attention_num_buckets", 32},
      {"tie_word_embeddings", false}, {"torch_dtype", "bfloat16"}, {"vocab_size", 32128}};
  return f;
}

}  // namespace dvs
