// T5 v1.1 encoder settings read from text_encoder/config.json (transformers' T5Config: a missing key takes its
// default). GPU-free; models/cogvideox/t5_encoder builds the network from it.
#pragma once
#include <cstdint>
#include <string_view>

#include <nlohmann/json.hpp>

namespace dvs {

struct T5EncoderConfig {
  // The feed-forward activation T5Config derives from feed_forward_proj (transformers' ACT2FN names).
  enum class Activation { gelu_tanh, silu };

  int64_t vocab_size = 0, d_model = 0, d_kv = 0, d_ff = 0, num_layers = 0, num_heads = 0;
  int64_t num_buckets = 32, max_distance = 128;
  float eps = 1e-6f;
  bool gated = true;
  Activation activation = Activation::gelu_tanh;

  int64_t inner() const { return num_heads * d_kv; }
  static T5EncoderConfig from_json(const nlohmann::json& config, std::string_view origin = "config.json");
};

}  // namespace dvs
