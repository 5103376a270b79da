#include "models/cogvideox/t5_encoder.hpp"

#include <cmath>
#include <string>

#include "dvs/error.hpp"
#include "models/activation_plan.hpp"
#include "models/cogvideox/tokenizer.hpp"
#include "tensor/ops_attention.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_layout.hpp"
#include "tensor/ops_norm.hpp"
#include "vk/context.hpp"

namespace dvs::models {

namespace {

std::string block(int64_t i) { return "encoder.block." + std::to_string(i) + "."; }

}  // namespace

int64_t t5_relative_position_bucket(int64_t relative_position, bool bidirectional, int64_t num_buckets,
                                    int64_t max_distance) {
  int64_t bucket = 0;
  int64_t n = relative_position;
  if (bidirectional) {
    num_buckets /= 2;
    if (n > 0) bucket += num_buckets;
    n = n < 0 ? -n : n;
  } else {
    n = n < 0 ? -n : 0;  // -min(n, 0)
  }
  const int64_t max_exact = num_buckets / 2;
  if (n < max_exact) return bucket + n;
  // torch: max_exact + (log(n.float() / max_exact) / math.log(max_distance / max_exact) * (nb - max_exact)).long()
  // in float32 (the python scalars are converted to the tensor's dtype).
  const float ratio = float(n) / float(max_exact);
  const float denom = float(std::log(double(max_distance) / double(max_exact)));
  const float v = std::log(ratio) / denom * float(num_buckets - max_exact);
  int64_t large = max_exact + int64_t(v);
  if (large > num_buckets - 1) large = num_buckets - 1;
  return bucket + large;
}

struct T5Encoder::Activations {
  Tensor h, xn, qkv, attn, ff_a, ff_b, words;
};

T5Encoder::T5Encoder(vk::Context& ctx, const std::filesystem::path& dir, WeightResidency residency, int stream_slots)
    : T5Encoder(ctx, ComponentWeights(ctx, dir), residency, stream_slots) {}

T5Encoder::T5Encoder(vk::Context& ctx, ComponentWeights weights, WeightResidency residency, int stream_slots)
    : ctx_(ctx), weights_(std::move(weights)), cfg_(T5EncoderConfig::from_json(weights_.config(), (weights_.dir() / "config.json").string())) {
  embedding_ = weights_.get("shared.weight", {cfg_.vocab_size, cfg_.d_model});
  if (embedding_.dtype() != DType::f32 && embedding_.dtype() != DType::bf16 && embedding_.dtype() != DType::f16)
    throw Error(weights_.dir().string() + ": shared.weight must be f32, bf16 or f16, got " + embedding_.describe());
  if (embedding_.dtype() != DType::f32 && cfg_.d_model % 2 != 0)
    throw Error(weights_.dir().string() + ": 16-bit token embeddings need an even d_model");
  const int64_t D = cfg_.d_model, I = cfg_.inner(), F = cfg_.d_ff;
  // Upload (and shape-check) every tensor now, so a bad checkpoint fails at load and not mid-recording. Streamed
  // layer weights are shape-checked from their headers and go to host memory instead.
  std::vector<std::vector<std::string>> streamed(size_t(cfg_.num_layers));
  for (int64_t i = 0; i < cfg_.num_layers; ++i) {
    const std::string b = block(i);
    auto need = [&](const std::string& name, const Shape& shape) {
      if (residency == WeightResidency::resident) {
        weights_.get(name, shape);
      } else {
        weights_.check(name, shape);
        streamed[size_t(i)].push_back(name);
      }
    };
    for (const char* p : {"q", "k", "v"}) need(b + "layer.0.SelfAttention." + p + ".weight", {I, D});
    need(b + "layer.0.SelfAttention.o.weight", {D, I});
    need(b + "layer.0.layer_norm.weight", {D});
    if (cfg_.gated) {
      need(b + "layer.1.DenseReluDense.wi_0.weight", {F, D});
      need(b + "layer.1.DenseReluDense.wi_1.weight", {F, D});
    } else {
      need(b + "layer.1.DenseReluDense.wi.weight", {F, D});
    }
    need(b + "layer.1.DenseReluDense.wo.weight", {D, F});
    need(b + "layer.1.layer_norm.weight", {D});
  }
  weights_.get("encoder.final_layer_norm.weight", {D});
  if (cfg_.num_layers > 0)
    weights_.get(block(0) + "layer.0.SelfAttention.relative_attention_bias.weight", {cfg_.num_buckets, cfg_.num_heads});
  if (residency == WeightResidency::stream && cfg_.num_layers > 0)
    stream_ = std::make_unique<BlockStream>(
        ctx_, weights_, cfg_.num_layers, [&](int64_t i) { return streamed[size_t(i)]; }, stream_slots, "T5 layers");
}

const Tensor& T5Encoder::position_bias(int64_t len) {
  if (auto it = position_bias_.find(len); it != position_bias_.end()) return it->second;
  const int64_t H = cfg_.num_heads;
  HostTensor bias({H, len, len}, DType::f32);
  float* b = bias.as<float>();
  if (cfg_.num_layers > 0) {
    const std::vector<float> table =
        weights_.get(block(0) + "layer.0.SelfAttention.relative_attention_bias.weight").download(ctx_).to_f32();
    for (int64_t i = 0; i < len; ++i)
      for (int64_t j = 0; j < len; ++j) {
        const int64_t bucket = t5_relative_position_bucket(j - i, true, cfg_.num_buckets, cfg_.max_distance);
        for (int64_t h = 0; h < H; ++h) b[(h * len + i) * len + j] = table[size_t(bucket * H + h)];
      }
  }
  return position_bias_.emplace(len, Tensor::upload(ctx_, bias, "T5 position bias")).first->second;
}

T5Encoder::Activations T5Encoder::plan(const T5EncoderConfig& cfg, bool embedding_16bit, ActivationPlan& p, int64_t B,
                                       int64_t L) {
  const int64_t D = cfg.d_model, I = cfg.inner(), F = cfg.d_ff;
  Activations a;
  a.h = p.make({B, L, D});
  a.xn = p.make({B, L, D});
  a.qkv = p.make({B, L, 3 * I});
  a.attn = p.make({B, L, I});
  a.ff_a = p.make({B, L, F});
  if (cfg.gated) a.ff_b = p.make({B, L, F});
  if (embedding_16bit) a.words = p.make({B * L, D / 2}, DType::i32);
  return a;
}

vk::ArenaLayout T5Encoder::arena_layout(const T5EncoderConfig& config, bool embedding_16bit, uint64_t alignment,
                                       int64_t batch, int64_t len, uint64_t alloc_limit) {
  ActivationPlan p(alignment, alloc_limit, "T5 activation arena");
  plan(config, embedding_16bit, p, batch, len);
  return p.layout();
}

uint64_t T5Encoder::arena_bytes(const T5EncoderConfig& config, bool embedding_16bit, uint64_t alignment, int64_t batch,
                                int64_t len, uint64_t alloc_limit) {
  return arena_layout(config, embedding_16bit, alignment, batch, len, alloc_limit).bytes();
}

vk::ArenaLayout T5Encoder::arena_layout(int64_t batch, int64_t len) const {
  return arena_layout(cfg_, embedding_.dtype() != DType::f32, ctx_.allocator().alignment(), batch, len,
                      ctx_.allocator().max_allocation());
}

uint64_t T5Encoder::arena_bytes(int64_t batch, int64_t len) const { return arena_layout(batch, len).bytes(); }

void T5Encoder::record(vk::Recorder& rec, vk::Arena& arena, const Tensor& ids, const Tensor* key_mask,
                       const Tensor& out, const std::vector<Tensor>* taps) {
  if (ids.rank() != 2 || ids.dtype() != DType::i32) throw Error("internal: T5Encoder: ids must be i32 [B, L], got " + ids.describe());
  const int64_t B = ids.dim(0), L = ids.dim(1);
  const int64_t D = cfg_.d_model, I = cfg_.inner(), H = cfg_.num_heads, Dh = cfg_.d_kv;
  ops::expect_shape("T5Encoder", "out", out, {B, L, D});
  if (key_mask) ops::expect_shape("T5Encoder", "key_mask", *key_mask, {B, L});
  if (taps && int64_t(taps->size()) != cfg_.num_layers + 1)
    throw Error("internal: T5Encoder: taps must hold num_layers + 1 tensors");
  auto it = position_bias_.find(L);
  if (it == position_bias_.end()) throw Error("internal: T5Encoder: position_bias(L) not created before recording");
  const Tensor& bias = it->second;

  ActivationPlan p(arena);
  Activations a = plan(cfg_, embedding_.dtype() != DType::f32, p, B, L);
  if (stream_) stream_->begin_call(rec);  // the uploads' schedule for this recording's submission
  auto tap = [&](size_t i, const Tensor& t) {
    if (taps) rec.copy(t.buffer(), (*taps)[i].buffer(), t.bytes());
  };

  // Token embedding: row gather; 16-bit tables are gathered as pairs of values (one i32 each) and widened.
  const Tensor flat_ids = ids.reshape({B * L});
  if (embedding_.dtype() == DType::f32) {
    ops::gather_rows(rec, embedding_, flat_ids, a.h.reshape({B * L, D}));
  } else {
    const Tensor table = Tensor::on(embedding_.buffer(), {cfg_.vocab_size, D / 2}, DType::i32);
    ops::gather_rows(rec, table, flat_ids, a.words);
    ops::cast(rec, Tensor::on(a.words.buffer(), {B * L * D}, embedding_.dtype()), a.h.reshape({B * L * D}));
  }
  tap(0, a.h);

  ops::AttentionShape ashape{B, H, Dh, L, L};
  ops::AttentionOptions aopt;
  aopt.scale = 1.0f;  // T5 does not scale its logits
  aopt.bias = &bias;
  aopt.key_mask = key_mask;
  const int64_t rows = B * L;
  for (int64_t i = 0; i < cfg_.num_layers; ++i) {
    const std::string b = block(i);
    const std::string att = b + "layer.0.SelfAttention.";
    if (stream_) stream_->mark_block(rec, i);
    // Layer i's weight `name`: resident, or in the stream slot layer i is uploaded to.
    auto weight = [&](const std::string& name) { return stream_ ? stream_->get(i, name) : weights_.get(name); };
    ops::rmsnorm(rec, a.h, a.xn, weight(b + "layer.0.layer_norm.weight"), cfg_.eps);
    // q, k, v into column slices of one [B*L, 3I] buffer.
    const char* names[3] = {"q", "k", "v"};
    // T5's activations (and the products of its FFN, the input of wo) exceed fp16 range: every linear here
    // demands fp32 operands (no tensor-core kernel, whose operands are fp16).
    ops::LinearEpilogue fp32_ops;
    fp32_ops.fp16_operands_ok = false;
    for (int w = 0; w < 3; ++w) {
      ops::LinearShape s;
      s.m = rows;
      s.n = I;
      s.k = D;
      s.y_row_stride = 3 * I;
      ops::linear_batched(rec, a.xn, weight(att + names[w] + ".weight"),
                          element_range(a.qkv, w * I, a.qkv.numel() - w * I), s, fp32_ops);
    }
    ops::attention(rec, ashape, ops::fused_qkv_operand(a.qkv, 0, H, Dh), ops::fused_qkv_operand(a.qkv, 1, H, Dh),
                   ops::fused_qkv_operand(a.qkv, 2, H, Dh), ops::AttentionOperand{a.attn}, aopt);
    ops::LinearEpilogue res = fp32_ops;
    res.residual = a.h;
    ops::linear(rec, a.attn, weight(att + "o.weight"), a.h, res);

    const std::string ff = b + "layer.1.DenseReluDense.";
    ops::rmsnorm(rec, a.h, a.xn, weight(b + "layer.1.layer_norm.weight"), cfg_.eps);
    ops::LinearEpilogue act = fp32_ops;
    act.activation =
        cfg_.activation == T5EncoderConfig::Activation::silu ? ops::Activation::silu : ops::Activation::gelu_tanh;
    if (cfg_.gated) {
      ops::linear(rec, a.xn, weight(ff + "wi_0.weight"), a.ff_a, act);
      ops::linear(rec, a.xn, weight(ff + "wi_1.weight"), a.ff_b, fp32_ops);
      ops::mul(rec, a.ff_a, a.ff_b, a.ff_a);
    } else {
      ops::linear(rec, a.xn, weight(ff + "wi.weight"), a.ff_a, act);
    }
    ops::linear(rec, a.ff_a, weight(ff + "wo.weight"), a.h, res);
    if (i + 1 < cfg_.num_layers) tap(size_t(i + 1), a.h);
    rec.boundary("T5 layer " + std::to_string(i + 1) + "/" + std::to_string(cfg_.num_layers));  // one submission per layer
  }
  ops::rmsnorm(rec, a.h, out, weights_.get("encoder.final_layer_norm.weight"), cfg_.eps);
  tap(size_t(cfg_.num_layers), out);
}

Tensor T5Encoder::encode(const std::vector<std::vector<int32_t>>& ids, const std::vector<std::vector<float>>& key_mask,
                         std::vector<HostTensor>* hidden_states) {
  if (ids.empty() || ids[0].empty()) throw Error("T5Encoder::encode: no tokens");
  const int64_t B = int64_t(ids.size()), L = int64_t(ids[0].size()), D = cfg_.d_model;
  HostTensor hid({B, L}, DType::i32);
  for (int64_t b = 0; b < B; ++b) {
    if (int64_t(ids[size_t(b)].size()) != L) throw Error("T5Encoder::encode: token rows must have the same length");
    for (int64_t l = 0; l < L; ++l) {
      const int32_t id = ids[size_t(b)][size_t(l)];
      if (id < 0 || id >= cfg_.vocab_size)
        throw Error("T5Encoder::encode: token id " + std::to_string(id) + " outside the vocabulary of " +
                    std::to_string(cfg_.vocab_size));
      hid.as<int32_t>()[b * L + l] = id;
    }
  }
  const Tensor dev_ids = Tensor::upload(ctx_, hid, "T5 token ids");
  Tensor dev_mask;
  if (!key_mask.empty()) {
    if (int64_t(key_mask.size()) != B) throw Error("T5Encoder::encode: the mask must have one row per prompt");
    HostTensor hm({B, L}, DType::f32);
    for (int64_t b = 0; b < B; ++b) {
      if (int64_t(key_mask[size_t(b)].size()) != L) throw Error("T5Encoder::encode: mask rows must have L values");
      for (int64_t l = 0; l < L; ++l) hm.as<float>()[b * L + l] = key_mask[size_t(b)][size_t(l)];
    }
    dev_mask = Tensor::upload(ctx_, hm, "T5 attention mask");
  }
  position_bias(L);
  Tensor out = Tensor::empty(ctx_, {B, L, D}, DType::f32, "T5 last_hidden_state");
  std::vector<Tensor> taps;
  if (hidden_states)
    for (int64_t i = 0; i <= cfg_.num_layers; ++i) taps.push_back(Tensor::empty(ctx_, {B, L, D}, DType::f32, "T5 hidden state"));
  vk::Arena& arena = arena_for(ctx_, arena_, arena_layout(B, L), "T5 activation arena");
  vk::Recorder rec(ctx_);
  rec.begin();
  record(rec, arena, dev_ids, dev_mask.defined() ? &dev_mask : nullptr, out, hidden_states ? &taps : nullptr);
  rec.end();
  rec.submit();
  if (hidden_states) {
    hidden_states->clear();
    for (const Tensor& t : taps) hidden_states->push_back(t.download(ctx_));
  }
  return out;
}

Tensor T5Encoder::encode_prompts(const T5Tokenizer& tokenizer, const std::vector<std::string>& prompts,
                                 int max_length) {
  std::vector<std::vector<int32_t>> ids;
  for (const std::string& p : prompts) ids.push_back(tokenizer.encode_padded(p, max_length));
  return encode(ids);
}

}  // namespace dvs::models
