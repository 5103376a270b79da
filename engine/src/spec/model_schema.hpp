// The tensors a checkpoint must hold, derived from its config.json the way the libraries build their
// modules: transformers' T5EncoderModel, diffusers' CogVideoXTransformer3DModel and AutoencoderKLCogVideoX.
// Any sizes from the config work (layer counts, heads, channel lists), not just the real model's.
#pragma once
#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "io/host_tensor.hpp"

namespace dvs {

class WeightSet;

struct TensorSpec {
  std::string name;
  Shape shape;
  bool optional = false;  // may be absent (tied weights); checked when present
};

struct Schema {
  std::string class_name;
  std::vector<TensorSpec> tensors;  // in module order
};

struct SchemaIssue {
  enum class Kind { missing, unexpected, wrong_shape };
  Kind kind;
  std::string tensor;
  Shape expected, found;
  std::string message() const;  // "tensor 'x': expected shape [32,8,2,2], found [32,4,2,2]"
};

// Whether schema_for knows the class.
bool has_schema(std::string_view class_name);
// The schema for a class from its config. Throws dvs::Error for an unknown class or a config value of the
// wrong type / out of range (`origin`, e.g. the config path, prefixes the message).
Schema schema_for(std::string_view class_name, const nlohmann::json& config, std::string_view origin = "config.json");

Schema t5_encoder_schema(const nlohmann::json& config, std::string_view origin = "config.json");
Schema cogvideox_transformer_schema(const nlohmann::json& config, std::string_view origin = "config.json");
Schema cogvideox_vae_schema(const nlohmann::json& config, std::string_view origin = "config.json");

// Every missing, unexpected and wrong-shape tensor, sorted by tensor name.
std::vector<SchemaIssue> check_schema(const Schema& schema, const std::vector<std::pair<std::string, Shape>>& found);
std::vector<SchemaIssue> check_schema(const Schema& schema, const WeightSet& weights);
// Throws dvs::Error listing the issues (the first 20 and a count) if there are any.
void require_schema(const Schema& schema, const WeightSet& weights, std::string_view origin);

}  // namespace dvs
