// T5 v1.1 encoder as transformers' T5EncoderModel computes it and CogVideoX calls it:
//   h = shared[ids]
//   per block: h += o(attn(rmsnorm(h)))  with UNSCALED logits + relative position bias (buckets from block 0's
//              relative_attention_bias, shared by every block) + optional key-padding mask
//              h += wo(act(wi_0 x) * wi_1 x), x = rmsnorm(h)   (gated-gelu: act = GELU tanh; non-gated: wo(act(wi x)))
//   out = rmsnorm_final(h)
// Every size comes from text_encoder/config.json; weights stay in their stored dtype (f32 or bf16).
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "models/block_stream.hpp"
#include "models/weights.hpp"
#include "spec/t5_config.hpp"
#include "tensor/ops_linear.hpp"
#include "tensor/tensor.hpp"
#include "vk/memory.hpp"
#include "vk/recorder.hpp"

namespace dvs {
class T5Tokenizer;
}

namespace dvs::models {

class ActivationPlan;

using dvs::T5EncoderConfig;  // spec/t5_config.hpp

// transformers' T5Attention._relative_position_bucket (fp32 log as torch computes it). relative_position =
// key position - query position.
int64_t t5_relative_position_bucket(int64_t relative_position, bool bidirectional, int64_t num_buckets,
                                    int64_t max_distance);

class T5Encoder {
 public:
  // `text_encoder_dir`: <model>/text_encoder (config.json + single or sharded safetensors).
  // `residency`: the layers' weights on the device, or streamed through `stream_slots` device slots (the
  // embedding table, the final norm and layer 0's relative position table stay resident).
  T5Encoder(vk::Context& ctx, const std::filesystem::path& text_encoder_dir,
            WeightResidency residency = WeightResidency::resident, int stream_slots = 2);
  // From weights already on the device (ComponentWeights' in-memory constructor; benchmarks).
  T5Encoder(vk::Context& ctx, ComponentWeights weights, WeightResidency residency = WeightResidency::resident,
            int stream_slots = 2);

  const T5EncoderConfig& config() const { return cfg_; }
  ComponentWeights& weights() { return weights_; }
  WeightResidency residency() const { return stream_ ? WeightResidency::stream : WeightResidency::resident; }
  const BlockStream* stream() const { return stream_.get(); }  // null when resident

  // ids: B rows of the same length L. key_mask: empty = no mask (how CogVideoX calls T5: pads attend), else
  // B rows of L values, 0 = padding key. Returns last_hidden_state f32 [B, L, d_model] (an owning tensor).
  // hidden_states (optional) receives transformers' output_hidden_states: [0] = embeddings, [i] = output of
  // block i-1 for 1 <= i < num_layers, [num_layers] = last_hidden_state (each f32 [B, L, d_model]).
  Tensor encode(const std::vector<std::vector<int32_t>>& ids, const std::vector<std::vector<float>>& key_mask = {},
                std::vector<HostTensor>* hidden_states = nullptr);

  // CogVideoX's _get_t5_prompt_embeds: every prompt tokenized with padding to max_length (ids end with </s>,
  // then <pad>) and encoded WITHOUT a mask, all prompts in one batch. Returns f32 [prompts, max_length, d_model].
  Tensor encode_prompts(const T5Tokenizer& tokenizer, const std::vector<std::string>& prompts, int max_length);

  // Records the forward into `rec` with activations from `arena` (at least arena_bytes(B, L)): ids i32 [B, L],
  // key_mask f32 [B, L] or null, out f32 [B, L, d_model]. taps (optional): num_layers + 1 tensors of out's
  // shape receiving the hidden states as in encode(). The position bias table for L must exist
  // (position_bias(L), created before recording).
  void record(vk::Recorder& rec, vk::Arena& arena, const Tensor& ids, const Tensor* key_mask, const Tensor& out,
              const std::vector<Tensor>* taps = nullptr);
  uint64_t arena_bytes(int64_t batch, int64_t len) const;
  vk::ArenaLayout arena_layout(int64_t batch, int64_t len) const;  // its blocks under the limit in force
  // The same from a config alone (memory planning without weights); embedding_16bit: shared.weight is bf16/f16;
  // alloc_limit: maxMemoryAllocationSize the arena's blocks are cut for (vk::Arena).
  static uint64_t arena_bytes(const T5EncoderConfig& config, bool embedding_16bit, uint64_t alignment, int64_t batch,
                              int64_t len, uint64_t alloc_limit = UINT64_MAX);
  static vk::ArenaLayout arena_layout(const T5EncoderConfig& config, bool embedding_16bit, uint64_t alignment,
                                      int64_t batch, int64_t len, uint64_t alloc_limit);

  // f32 [heads, L, L]: bias[h][i][j] = relative_attention_bias[bucket(j - i)][h] (cached per L).
  const Tensor& position_bias(int64_t len);

 private:
  struct Activations;
  static Activations plan(const T5EncoderConfig& cfg, bool embedding_16bit, ActivationPlan& p, int64_t batch,
                          int64_t len);

  vk::Context& ctx_;
  ComponentWeights weights_;
  T5EncoderConfig cfg_;
  Tensor embedding_;  // shared.weight as stored
  std::map<int64_t, Tensor> position_bias_;
  std::unique_ptr<vk::Arena> arena_;
  std::unique_ptr<BlockStream> stream_;  // the layers' weights, when streamed
};

}  // namespace dvs::models
