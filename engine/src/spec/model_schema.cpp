// Expected parameter names/shapes, mirroring the module trees of:
//   transformers  models/t5/modeling_t5.py                       (T5EncoderModel)
//   diffusers     models/transformers/cogvideox_transformer_3d.py (CogVideoXTransformer3DModel, CogVideoXBlock)
//                 models/embeddings.py  (CogVideoXPatchEmbed, TimestepEmbedding)
//                 models/normalization.py (CogVideoXLayerNormZero, AdaLayerNorm)
//                 models/attention_processor.py (Attention), models/attention.py (FeedForward)
//                 models/autoencoders/autoencoder_kl_cogvideox.py (AutoencoderKLCogVideoX)
// Defaults are the constructors' defaults, used when a config omits a key.
#include "spec/model_schema.hpp"

#include <algorithm>
#include <map>

#include "dvs/error.hpp"
#include "spec/config_values.hpp"
#include "spec/model_folder.hpp"

namespace dvs {
namespace {

using nlohmann::json;

// The schema reads configs strictly (spec/config_values.hpp): a config that is not an object is an error.
ConfigValues config_reader(const json& config, std::string_view origin) {
  ConfigValues c(config, origin);
  c.require_object();
  return c;
}

int64_t mul(const ConfigValues& c, std::initializer_list<int64_t> xs) {
  int64_t r = 1;
  for (int64_t x : xs)
    if (__builtin_mul_overflow(r, x, &r) || r > (int64_t(1) << 52))
      throw Error(c.origin() + ": sizes in the config multiply to an impossible tensor size");
  return r;
}

// Collects specs with the module-path prefixes the libraries' state_dict() produces.
struct Builder {
  Schema s;
  void add(std::string name, Shape shape, bool optional = false) {
    s.tensors.push_back({std::move(name), std::move(shape), optional});
  }
  void linear(const std::string& p, int64_t in, int64_t out, bool bias = true) {
    add(p + ".weight", {out, in});
    if (bias) add(p + ".bias", {out});
  }
  void layer_norm(const std::string& p, int64_t dim, bool affine = true, bool bias = true) {
    if (!affine) return;
    add(p + ".weight", {dim});
    if (bias) add(p + ".bias", {dim});
  }
  void conv3d(const std::string& p, int64_t in, int64_t out, int64_t k) {
    add(p + ".weight", {out, in, k, k, k});
    add(p + ".bias", {out});
  }
  void conv2d(const std::string& p, int64_t in, int64_t out, int64_t k, bool bias = true) {
    add(p + ".weight", {out, in, k, k});
    if (bias) add(p + ".bias", {out});
  }
};

std::string idx(const std::string& p, int64_t i) { return p + "." + std::to_string(i); }

// ---- CogVideoX VAE pieces -------------------------------------------------------------------------------

// CogVideoXSpatialNorm3D: GroupNorm(f) + two 1x1x1 causal convs from the latent (zq) channels.
void spatial_norm(Builder& b, const std::string& p, int64_t f, int64_t zq) {
  b.layer_norm(p + ".norm_layer", f);
  b.conv3d(p + ".conv_y.conv", zq, f, 1);
  b.conv3d(p + ".conv_b.conv", zq, f, 1);
}

// CogVideoXResnetBlock3D with temb_channels=0 (no temb_proj), conv_shortcut=False (1x1x1 SafeConv3d when the
// channel count changes); spatial norm in the decoder (zq > 0), GroupNorm in the encoder.
void resnet3d(Builder& b, const std::string& p, int64_t in, int64_t out, int64_t zq) {
  if (zq > 0) spatial_norm(b, p + ".norm1", in, zq);
  else b.layer_norm(p + ".norm1", in);
  b.conv3d(p + ".conv1.conv", in, out, 3);
  if (zq > 0) spatial_norm(b, p + ".norm2", out, zq);
  else b.layer_norm(p + ".norm2", out);
  b.conv3d(p + ".conv2.conv", out, out, 3);
  if (in != out) b.conv3d(p + ".conv_shortcut", in, out, 1);
}

}  // namespace

std::string SchemaIssue::message() const {
  switch (kind) {
    case Kind::missing: return "tensor '" + tensor + "' is missing (expected shape " + shape_list(expected) + ")";
    case Kind::unexpected:
      return "tensor '" + tensor + "' is unexpected (shape " + shape_list(found) + "); the config does not produce it";
    case Kind::wrong_shape:
      return "tensor '" + tensor + "': expected shape " + shape_list(expected) + ", found " + shape_list(found);
  }
  return tensor;
}

Schema t5_encoder_schema(const json& config, std::string_view origin) {
  const ConfigValues c = config_reader(config, origin);
  const int64_t vocab = c.integer("vocab_size", 32128, 1);
  const int64_t d = c.integer("d_model", 512, 1);
  const int64_t dkv = c.integer("d_kv", 64, 1);
  const int64_t dff = c.integer("d_ff", 2048, 1);
  const int64_t layers = c.integer("num_layers", 6, 0);
  const int64_t heads = c.integer("num_heads", 8, 1);
  const int64_t buckets = c.integer("relative_attention_num_buckets", 32, 1);
  // T5Config: "gated-gelu" -> gated (wi_0, wi_1); "relu"/"gelu" -> one wi. Anything else is rejected there.
  const std::string ffp = c.string("feed_forward_proj", "relu");
  const auto dash = ffp.find('-');
  const bool gated = dash != std::string::npos && ffp.substr(0, dash) == "gated";
  if ((dash != std::string::npos && !gated) || (gated && ffp.find('-', dash + 1) != std::string::npos) ||
      ffp.empty() || (gated && dash + 1 == ffp.size()))
    c.fail("feed_forward_proj", "must be 'ACT' or 'gated-ACT', got \"" + ffp + "\"");
  const int64_t inner = mul(c, {heads, dkv});
  mul(c, {vocab, d});

  Builder b;
  b.s.class_name = "T5EncoderModel";
  b.add("shared.weight", {vocab, d});
  b.add("encoder.embed_tokens.weight", {vocab, d}, /*optional: tied to shared.weight*/ true);
  for (int64_t i = 0; i < layers; ++i) {
    const std::string p = idx("encoder.block", i);
    const std::string a = p + ".layer.0.SelfAttention";
    b.linear(a + ".q", d, inner, false);
    b.linear(a + ".k", d, inner, false);
    b.linear(a + ".v", d, inner, false);
    b.linear(a + ".o", inner, d, false);
    if (i == 0) b.add(a + ".relative_attention_bias.weight", {buckets, heads});  // only block 0 has it
    b.add(p + ".layer.0.layer_norm.weight", {d});
    const std::string f = p + ".layer.1.DenseReluDense";
    if (gated) {
      b.linear(f + ".wi_0", d, dff, false);
      b.linear(f + ".wi_1", d, dff, false);
    } else {
      b.linear(f + ".wi", d, dff, false);
    }
    b.linear(f + ".wo", dff, d, false);
    b.add(p + ".layer.1.layer_norm.weight", {d});
  }
  b.add("encoder.final_layer_norm.weight", {d});
  return b.s;
}

Schema cogvideox_transformer_schema(const json& config, std::string_view origin) {
  const ConfigValues c = config_reader(config, origin);
  const int64_t heads = c.integer("num_attention_heads", 30, 1);
  const int64_t head_dim = c.integer("attention_head_dim", 64, 1);
  const int64_t in_ch = c.integer("in_channels", 16, 1);
  const int64_t out_ch = c.integer("out_channels", 16, 1);
  const int64_t temb = c.integer("time_embed_dim", 512, 1);
  const int64_t ofs = c.opt_integer("ofs_embed_dim", 0).value_or(0);  // `if ofs_embed_dim:` -> 0/null = off
  const int64_t text = c.integer("text_embed_dim", 4096, 1);
  const int64_t layers = c.integer("num_layers", 30, 0);
  const bool attn_bias = c.boolean("attention_bias", true);
  const int64_t sw = c.integer("sample_width", 90, 0);
  const int64_t sh = c.integer("sample_height", 60, 0);
  const int64_t sf = c.integer("sample_frames", 49, 1);
  const int64_t p = c.integer("patch_size", 2, 1);
  const auto pt = c.opt_integer("patch_size_t", 1);
  const int64_t tcr = c.integer("temporal_compression_ratio", 4, 1);
  const int64_t text_len = c.integer("max_text_seq_length", 226, 0);
  const std::string act = c.string("activation_fn", "gelu-approximate");
  const bool affine = c.boolean("norm_elementwise_affine", true);
  const bool rope = c.boolean("use_rotary_positional_embeddings", false);
  const bool learned = c.boolean("use_learned_positional_embeddings", false);
  const bool patch_bias = c.boolean("patch_bias", true);
  if (!rope && learned)
    c.fail("use_learned_positional_embeddings", "is true without use_rotary_positional_embeddings (diffusers rejects this)");

  const int64_t dim = mul(c, {heads, head_dim});
  const int64_t ff_inner = mul(c, {dim, 4});  // FeedForward(mult=4)
  // FeedForward's first layer: GEGLU/SwiGLU project to twice the inner width; GELU variants do not.
  int64_t ff_proj_out;
  if (act == "gelu" || act == "gelu-approximate" || act == "geglu-approximate" || act == "linear-silu")
    ff_proj_out = ff_inner;
  else if (act == "geglu" || act == "swiglu")
    ff_proj_out = mul(c, {ff_inner, 2});
  else
    c.fail("activation_fn", "\"" + act + "\" is not a FeedForward activation diffusers knows");

  Builder b;
  b.s.class_name = "CogVideoXTransformer3DModel";
  // CogVideoXPatchEmbed: Conv2d for CogVideoX 1.0, Linear over (C, pt, p, p) patches for 1.5.
  if (!pt) b.conv2d("patch_embed.proj", in_ch, dim, p, patch_bias);
  else b.linear("patch_embed.proj", mul(c, {in_ch, p, p, *pt}), dim);
  b.linear("patch_embed.text_proj", text, dim);
  // The sincos table is a non-persistent buffer; only the learned one is saved (text rows included).
  if (learned) {
    const int64_t patches = mul(c, {sh / p, sw / p, (sf - 1) / tcr + 1});
    b.add("patch_embed.pos_embedding", {1, text_len + patches, dim});
  }
  b.linear("time_embedding.linear_1", dim, temb);
  b.linear("time_embedding.linear_2", temb, temb);
  if (ofs > 0) {
    b.linear("ofs_embedding.linear_1", ofs, ofs);
    b.linear("ofs_embedding.linear_2", ofs, ofs);
  }
  for (int64_t i = 0; i < layers; ++i) {
    const std::string blk = idx("transformer_blocks", i);
    // CogVideoXLayerNormZero: Linear(temb -> 6*dim) + LayerNorm(dim).
    b.linear(blk + ".norm1.linear", temb, mul(c, {dim, 6}));
    b.layer_norm(blk + ".norm1.norm", dim, affine);
    // Attention(qk_norm="layer_norm", eps=1e-6): per-head LayerNorm with the default elementwise_affine=True.
    b.layer_norm(blk + ".attn1.norm_q", head_dim);
    b.layer_norm(blk + ".attn1.norm_k", head_dim);
    b.linear(blk + ".attn1.to_q", dim, dim, attn_bias);
    b.linear(blk + ".attn1.to_k", dim, dim, attn_bias);
    b.linear(blk + ".attn1.to_v", dim, dim, attn_bias);
    b.linear(blk + ".attn1.to_out.0", dim, dim, true);  // attention_out_bias defaults to True
    b.linear(blk + ".norm2.linear", temb, mul(c, {dim, 6}));
    b.layer_norm(blk + ".norm2.norm", dim, affine);
    b.linear(blk + ".ff.net.0.proj", dim, ff_proj_out);
    b.linear(blk + ".ff.net.2", ff_inner, dim);
  }
  b.layer_norm("norm_final", dim, affine);
  // AdaLayerNorm(temb, output_dim=2*dim): Linear(temb -> 2*dim) + LayerNorm(dim).
  b.linear("norm_out.linear", temb, mul(c, {dim, 2}));
  b.layer_norm("norm_out.norm", dim, affine);
  b.linear("proj_out", dim, pt ? mul(c, {p, p, *pt, out_ch}) : mul(c, {p, p, out_ch}));
  return b.s;
}

Schema cogvideox_vae_schema(const json& config, std::string_view origin) {
  const ConfigValues c = config_reader(config, origin);
  const int64_t in_ch = c.integer("in_channels", 3, 1);
  const int64_t out_ch = c.integer("out_channels", 3, 1);
  const std::vector<int64_t> boc = c.integers("block_out_channels", {128, 256, 256, 512}, 1);
  const int64_t latent = c.integer("latent_channels", 16, 1);
  const int64_t lpb = c.integer("layers_per_block", 3, 0);
  const bool quant = c.boolean("use_quant_conv", false);
  const bool post_quant = c.boolean("use_post_quant_conv", false);
  const auto down = c.strings("down_block_types", std::vector<std::string>(4, "CogVideoXDownBlock3D"));
  const auto up = c.strings("up_block_types", std::vector<std::string>(4, "CogVideoXUpBlock3D"));
  if (down.size() != boc.size() || up.size() != boc.size())
    c.fail("block_out_channels", "has " + std::to_string(boc.size()) + " entries but down_block_types/up_block_types have " +
                                     std::to_string(down.size()) + "/" + std::to_string(up.size()));
  for (const auto& t : down)
    if (t != "CogVideoXDownBlock3D") c.fail("down_block_types", "holds \"" + t + "\"; only CogVideoXDownBlock3D exists");
  for (const auto& t : up)
    if (t != "CogVideoXUpBlock3D") c.fail("up_block_types", "holds \"" + t + "\"; only CogVideoXUpBlock3D exists");
  const size_t n = boc.size();

  Builder b;
  b.s.class_name = "AutoencoderKLCogVideoX";
  // Encoder: conv_in, down blocks (downsampler on all but the last), 2-resnet mid block, GroupNorm, conv_out
  // to mean and logvar (2 * latent channels).
  b.conv3d("encoder.conv_in.conv", in_ch, boc[0], 3);
  for (size_t i = 0; i < n; ++i) {
    const std::string p = idx("encoder.down_blocks", int64_t(i));
    const int64_t in = i == 0 ? boc[0] : boc[i - 1];
    for (int64_t j = 0; j < lpb; ++j) resnet3d(b, idx(p + ".resnets", j), j == 0 ? in : boc[i], boc[i], 0);
    if (i + 1 < n) b.conv2d(p + ".downsamplers.0.conv", boc[i], boc[i], 3);
  }
  for (int j = 0; j < 2; ++j) resnet3d(b, idx("encoder.mid_block.resnets", j), boc[n - 1], boc[n - 1], 0);
  b.layer_norm("encoder.norm_out", boc[n - 1]);
  b.conv3d("encoder.conv_out.conv", boc[n - 1], mul(c, {latent, 2}), 3);

  // Decoder: reversed channels, spatial norms conditioned on the latent, layers_per_block + 1 resnets per up
  // block, upsampler on all but the last.
  std::vector<int64_t> rev(boc.rbegin(), boc.rend());
  b.conv3d("decoder.conv_in.conv", latent, rev[0], 3);
  for (int j = 0; j < 2; ++j) resnet3d(b, idx("decoder.mid_block.resnets", j), rev[0], rev[0], latent);
  for (size_t i = 0; i < n; ++i) {
    const std::string p = idx("decoder.up_blocks", int64_t(i));
    const int64_t in = i == 0 ? rev[0] : rev[i - 1];
    for (int64_t j = 0; j <= lpb; ++j) resnet3d(b, idx(p + ".resnets", j), j == 0 ? in : rev[i], rev[i], latent);
    if (i + 1 < n) b.conv2d(p + ".upsamplers.0.conv", rev[i], rev[i], 3);
  }
  spatial_norm(b, "decoder.norm_out", rev[n - 1], latent);
  b.conv3d("decoder.conv_out.conv", rev[n - 1], out_ch, 3);
  // As diffusers builds them: sized from the VAE's out_channels (not latent_channels), 1x1x1 SafeConv3d.
  if (quant) b.conv3d("quant_conv", mul(c, {out_ch, 2}), mul(c, {out_ch, 2}), 1);
  if (post_quant) b.conv3d("post_quant_conv", out_ch, out_ch, 1);
  return b.s;
}

bool has_schema(std::string_view cls) {
  return cls == "T5EncoderModel" || cls == "CogVideoXTransformer3DModel" || cls == "AutoencoderKLCogVideoX";
}

Schema schema_for(std::string_view cls, const json& config, std::string_view origin) {
  if (cls == "T5EncoderModel") return t5_encoder_schema(config, origin);
  if (cls == "CogVideoXTransformer3DModel") return cogvideox_transformer_schema(config, origin);
  if (cls == "AutoencoderKLCogVideoX") return cogvideox_vae_schema(config, origin);
  throw Error(std::string(origin) + ": no weight schema for class '" + std::string(cls) +
              "' (known: T5EncoderModel, CogVideoXTransformer3DModel, AutoencoderKLCogVideoX)");
}

std::vector<SchemaIssue> check_schema(const Schema& schema, const std::vector<std::pair<std::string, Shape>>& found) {
  std::map<std::string, const TensorSpec*> expected;
  for (const auto& t : schema.tensors) expected.emplace(t.name, &t);
  std::map<std::string, const Shape*> have;
  for (const auto& [name, shape] : found) have.emplace(name, &shape);

  std::vector<SchemaIssue> issues;
  for (const auto& [name, spec] : expected) {
    const auto it = have.find(name);
    if (it == have.end()) {
      if (!spec->optional) issues.push_back({SchemaIssue::Kind::missing, name, spec->shape, {}});
    } else if (*it->second != spec->shape) {
      issues.push_back({SchemaIssue::Kind::wrong_shape, name, spec->shape, *it->second});
    }
  }
  for (const auto& [name, shape] : have)
    if (!expected.count(name)) issues.push_back({SchemaIssue::Kind::unexpected, name, {}, *shape});
  std::sort(issues.begin(), issues.end(), [](const SchemaIssue& a, const SchemaIssue& b) { return a.tensor < b.tensor; });
  return issues;
}

std::vector<SchemaIssue> check_schema(const Schema& schema, const WeightSet& weights) {
  std::vector<std::pair<std::string, Shape>> found;
  found.reserve(weights.size());
  for (const auto& [name, ref] : weights.entries()) found.emplace_back(name, ref.info->shape);
  return check_schema(schema, found);
}

void require_schema(const Schema& schema, const WeightSet& weights, std::string_view origin) {
  const auto issues = check_schema(schema, weights);
  if (issues.empty()) return;
  std::string msg = std::string(origin) + ": weights do not match " + schema.class_name + " as its config describes it (" +
                    std::to_string(issues.size()) + " problem" + (issues.size() == 1 ? "" : "s") + "):";
  for (size_t i = 0; i < issues.size() && i < 20; ++i) msg += "\n  " + issues[i].message();
  if (issues.size() > 20) msg += "\n  ... and " + std::to_string(issues.size() - 20) + " more";
  throw Error(msg);
}

}  // namespace dvs
