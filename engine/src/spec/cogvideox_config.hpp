// The CogVideoX networks' settings read from their config.json (diffusers' CogVideoXTransformer3DModel and
// AutoencoderKLCogVideoX constructors: a missing key takes the constructor's default). GPU-free, so memory
// planning, preflight and tools read them without a device; the models (models/cogvideox/) are built from them.
#pragma once
#include <cstdint>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace dvs {

struct CogVideoXTransformerConfig {
  int64_t heads = 0, head_dim = 0, in_channels = 0, out_channels = 0, time_embed_dim = 0, text_embed_dim = 0;
  int64_t num_layers = 0, patch_size = 2, max_text_seq_length = 0;
  int64_t sample_width = 0, sample_height = 0, sample_frames = 0, temporal_compression_ratio = 4;
  bool flip_sin_to_cos = true;
  float freq_shift = 0.0f;
  float norm_eps = 1e-5f;
  float spatial_interpolation_scale = 1.875f, temporal_interpolation_scale = 1.0f;
  bool norm_affine = true;
  bool attention_bias = true;
  bool rotary = true, learned_pos = false;

  int64_t dim() const { return heads * head_dim; }
  // Throws dvs::Error (prefixed with `origin`) for a value of the wrong type and for the layouts this port does
  // not run (CogVideoX 1.5 patching, the 2B sincos-only embedding, other activations).
  static CogVideoXTransformerConfig from_json(const nlohmann::json& config, std::string_view origin = "config.json");
};

struct VaeConfig {
  int64_t in_channels = 3, out_channels = 3, latent_channels = 16;
  std::vector<int64_t> block_out_channels;
  int64_t layers_per_block = 3, norm_num_groups = 32;
  float norm_eps = 1e-6f;
  int64_t temporal_compression_ratio = 4;
  double scaling_factor = 1.15258426;
  int64_t sample_height = 480, sample_width = 720;
  bool use_quant_conv = false, use_post_quant_conv = false;

  static VaeConfig from_json(const nlohmann::json& config);
  int64_t spatial_ratio() const { return int64_t(1) << (block_out_channels.size() - 1); }
  int64_t temporal_levels() const;  // log2(temporal_compression_ratio): down/up blocks that compress time
};

// THUDM/CogVideoX-5b-I2V's config.json files as published (the keys diffusers and transformers read): the
// built-in model `dvs plan --model cogvideox-5b-i2v` plans for without a download.
struct CogVideoXConfigFiles {
  nlohmann::json transformer, vae, text_encoder;
};
CogVideoXConfigFiles cogvideox_5b_i2v_config_files();

}  // namespace dvs
