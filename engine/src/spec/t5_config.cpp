#include "spec/t5_config.hpp"

#include <string>

#include "dvs/error.hpp"
#include "spec/config_values.hpp"

namespace dvs {
namespace {

T5EncoderConfig::Activation activation_named(const std::string& name, std::string_view origin) {
  // transformers ACT2FN: gelu_new / gelu_pytorch_tanh are the tanh approximation; silu == swish.
  if (name == "gelu_new" || name == "gelu_pytorch_tanh") return T5EncoderConfig::Activation::gelu_tanh;
  if (name == "silu" || name == "swish") return T5EncoderConfig::Activation::silu;
  throw Error(std::string(origin) + ": T5 activation '" + name +
              "' is not supported (gelu_new / gelu_pytorch_tanh / silu are)");
}

}  // namespace

T5EncoderConfig T5EncoderConfig::from_json(const nlohmann::json& c, std::string_view origin) {
  const ConfigValues v(c, origin);
  T5EncoderConfig r;
  r.vocab_size = v.integer_or_default("vocab_size", 32128, 1);
  r.d_model = v.integer_or_default("d_model", 512, 1);
  r.d_kv = v.integer_or_default("d_kv", 64, 1);
  r.d_ff = v.integer_or_default("d_ff", 2048, 1);
  r.num_layers = v.integer_or_default("num_layers", 6, 0);
  r.num_heads = v.integer_or_default("num_heads", 8, 1);
  r.num_buckets = v.integer_or_default("relative_attention_num_buckets", 32, 2);
  r.max_distance = v.integer_or_default("relative_attention_max_distance", 128, 1);
  r.eps = v.number_or_default("layer_norm_epsilon", r.eps);
  // T5Config: feed_forward_proj "gated-ACT" or "ACT"; "gated-gelu" means dense_act_fn = gelu_new.
  const std::string ffp = v.string("feed_forward_proj", "relu");
  r.gated = ffp.rfind("gated-", 0) == 0;
  // T5Config derives dense_act_fn from feed_forward_proj (the stored dense_act_fn is recomputed).
  std::string act = r.gated ? ffp.substr(6) : ffp;
  if (ffp == "gated-gelu") act = "gelu_new";
  r.activation = activation_named(act, origin);
  return r;
}

}  // namespace dvs
