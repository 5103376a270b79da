// CogVideoX transformer (diffusers CogVideoXTransformer3DModel, CogVideoX 1.0 layout as in 5B-I2V: Conv2d
// patch embedding, RoPE + optional learned positional embedding). One call records the whole forward into
// one vk::Recorder; activations live in one vk::Arena sized from the shapes.
//
//   emb    = linear_2(silu(linear_1(sinusoid(t))))                        [B, time_embed_dim]
//   x      = [text_proj(text) ; proj(patchify(latent))] + pos_embedding   [B, L + N, D], text rows first
//   block  : (shift, scale, gate, enc_shift, enc_scale, enc_gate) = norm1.linear(silu(emb))
//            n = LN(x)·(1 + scale) + shift (video rows) / enc_ variants (text rows)
//            q, k, v = to_q/k/v(n); per-head LayerNorm on q, k; RoPE on the video rows of q, k
//            x += gate · to_out(attention(q, k, v) / sqrt(Dh))  (enc_gate on text rows)
//            same adaLN with norm2; x += gate · ff.net.2(gelu_tanh(ff.net.0.proj(n)))
//   out    = unpatchify(proj_out(LN_out(norm_final(x_video))·(1 + scale) + shift)), (shift, scale) from
//            norm_out.linear(silu(emb)).                                [B, F, out_channels, H, W]
// The sequence is kept as one [B, L + N, D] buffer: the per-token ops are the same for text and video rows,
// only the modulation vectors differ. Per block, K and V are made for the whole sequence; q, the attention
// output and the FFN's hidden state only for one token chunk at a time (token_chunk: the text rows, then the
// video rows, in chunks sized from the device limits), so no activation grows with 4·D per token over the
// whole sequence. The block weights are resident or streamed (models/block_stream.hpp): the same recording
// either way, reading them from the stream's slots.
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string_view>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include "models/block_stream.hpp"
#include "models/cogvideox/lora.hpp"
#include "models/weights.hpp"
#include "spec/cogvideox_config.hpp"
#include "tensor/tensor.hpp"
#include "vk/memory.hpp"
#include "vk/recorder.hpp"

namespace dvs::models {

class ActivationPlan;

using dvs::CogVideoXTransformerConfig;  // spec/cogvideox_config.hpp

// Intermediate results of one forward (debug aid; host copies of the first ones the pack records).
struct CogVideoXTaps {
  HostTensor time_embedding;              // [B, time_embed_dim]
  HostTensor patch_embed;                 // [B, L + N, D]
  std::vector<HostTensor> block_hidden;   // per block, [B, N, D] video rows
  std::vector<HostTensor> block_encoder;  // per block, [B, L, D] text rows
  HostTensor norm_final;                  // [B, N, D]
  HostTensor proj_out;                    // [B, N, p*p*out_channels]
};

// diffusers CogVideoXPatchEmbed._get_positional_embeddings: the 3D sincos table [max_text_seq_length + N, D]
// (text rows zero) for a latent of `frames` x `height` x `width`, as get_3d_sincos_pos_embed(output_type="pt")
// computes it (grids in fp32, frequencies and sin/cos in fp64, rounded to fp32): per video token
// [temporal (D/4) | w (3D/8) | h (3D/8)], each part [sin | cos]. D must be a multiple of 16.
HostTensor cogvideox_sincos_pos_embedding(const CogVideoXTransformerConfig& config, int64_t frames, int64_t height,
                                          int64_t width);

class CogVideoXTransformer {
 public:
  // `transformer_dir`: <model>/transformer (config.json + single or sharded safetensors).
  // `residency`: the block weights on the device, or streamed through `stream_slots` device slots.
  CogVideoXTransformer(vk::Context& ctx, const std::filesystem::path& transformer_dir,
                       WeightResidency residency = WeightResidency::resident, int stream_slots = 2);
  // From weights already on the device (ComponentWeights' in-memory constructor; benchmarks). Streamed: the
  // block weights move to host memory.
  CogVideoXTransformer(vk::Context& ctx, ComponentWeights weights, WeightResidency residency = WeightResidency::resident,
                       int stream_slots = 2);

  const CogVideoXTransformerConfig& config() const { return cfg_; }
  ComponentWeights& weights() { return weights_; }
  WeightResidency residency() const { return stream_ ? WeightResidency::stream : WeightResidency::resident; }
  const BlockStream* stream() const { return stream_.get(); }  // null when resident
  BlockStream* stream() { return stream_.get(); }  // record_timestamps (tests, dvs-bench)
  // Block `block`'s tensor `suffix` ("attn1.to_q.weight"), wherever it lives (its stream slot when streamed).
  Tensor block_weight(int64_t block, const std::string& suffix);

  // Tokens per chunk of a call's per-token work (q, attention output, FFN hidden state [B, chunk, 4·D] f32):
  // within `limit` bytes (one binding and one allocation under the device's limits) and at most half the
  // residual stream [B, S, D] (not below kMinChunkTokens unless the limit says so), a multiple of the rows
  // that keep each video chunk's RoPE table rows 256-byte aligned. The chunks: [0, L) then [L, S) in pieces.
  static constexpr int64_t kMinChunkTokens = 1024;
  static int64_t token_chunk(const CogVideoXTransformerConfig& config, int64_t batch, int64_t seq_len, uint64_t limit);

  // latent f32 [B, F, in_channels, H, W] (H, W multiples of patch_size); text f32 [B, L, text_embed_dim];
  // timesteps: B values, or 1 value used for every row. RoPE tables come from the ops_position builder for
  // this F×H×W. Returns f32 [B, F, out_channels, H, W] (an owning tensor).
  Tensor forward(const Tensor& latent, const Tensor& text, std::span<const float> timesteps,
                 CogVideoXTaps* taps = nullptr);

  // Records the forward: timesteps f32 [B], out f32 [B, F, out_channels, H, W], activations from `arena`
  // (at least arena_bytes(...)). rope_tables() / positional_embedding() for this size must exist already
  // (forward() creates them). `taps` (optional): device tensors receiving copies, in CogVideoXTaps order
  // (time embedding [B,T], sequence after patch_embed [B,S,D], after each block [B,S,D], after norm_final
  // [B,S,D], proj_out [B,N,p*p*Cout]).
  void record(vk::Recorder& rec, vk::Arena& arena, const Tensor& latent, const Tensor& text, const Tensor& timesteps,
              const Tensor& out, const std::vector<Tensor>* taps = nullptr);
  uint64_t arena_bytes(int64_t batch, int64_t frames, int64_t height, int64_t width, int64_t text_len) const;
  // Its blocks under the allocation limit in force (what the arena of that call is made of).
  vk::ArenaLayout arena_layout(int64_t batch, int64_t frames, int64_t height, int64_t width, int64_t text_len) const;
  // The same from a config alone (memory planning without weights); `alignment`: the allocator's;
  // alloc_limit: maxMemoryAllocationSize the arena's blocks are cut for (vk::Arena); chunk_limit: the bytes
  // token_chunk keeps a chunk's FFN state within (min(maxStorageBufferRange, maxMemoryAllocationSize)).
  static uint64_t arena_bytes(const CogVideoXTransformerConfig& config, uint64_t alignment, int64_t batch,
                              int64_t frames, int64_t height, int64_t width, int64_t text_len, int64_t lora_rank = 0,
                              uint64_t alloc_limit = UINT64_MAX, uint64_t chunk_limit = UINT64_MAX);
  static vk::ArenaLayout arena_layout(const CogVideoXTransformerConfig& config, uint64_t alignment, int64_t batch,
                                      int64_t frames, int64_t height, int64_t width, int64_t text_len,
                                      int64_t lora_rank, uint64_t alloc_limit, uint64_t chunk_limit = UINT64_MAX);

  // LoRA on the attention projections (transformer_blocks.<i>.attn1.{to_q,to_k,to_v,to_out.0}), applied as two
  // extra GEMMs per adapted projection (see models/lora.hpp). Replaces any previous set; an adapter on another
  // module or with mismatched shapes is an error naming it.
  void set_lora(std::map<std::string, LoraAdapter> adapters);
  void clear_lora();

  // Gives a call's memory back: the activation arena and the cached RoPE / positional tables (the next call
  // makes them again). For a caller done with one call size, and for measuring one call from nothing.
  void release_call_memory();

  // Device RoPE tables (cos, sin) f32 [F*Hp*Wp, head_dim] for a latent F×H×W (cached).
  const std::pair<Tensor, Tensor>& rope_tables(int64_t frames, int64_t height, int64_t width);
  // The f32 positional embedding [L + N, D] added after the patch embedding for latent F×H×W, as diffusers'
  // CogVideoXPatchEmbed chooses it: the learned table when (F - 1)·temporal_compression + 1 == sample_frames,
  // else the 3D sincos table of that size. Undefined tensor when the model uses none (5B T2V). Throws for
  // sizes diffusers rejects (H, W other than the config's; text length other than max_text_seq_length).
  const Tensor& positional_embedding(int64_t frames, int64_t height, int64_t width, int64_t text_len);

 private:
  struct Activations;
  static Activations plan(const CogVideoXTransformerConfig& cfg, ActivationPlan& p, int64_t B, int64_t F, int64_t H,
                          int64_t W, int64_t L, int64_t lora_rank, int64_t chunk);
  const LoraAdapter* lora(const std::string& module) const;
  void check_weights(WeightResidency residency, int stream_slots);
  uint64_t chunk_limit() const;  // min(maxStorageBufferRange, maxMemoryAllocationSize) in force

  vk::Context& ctx_;
  ComponentWeights weights_;
  CogVideoXTransformerConfig cfg_;
  std::map<std::tuple<int64_t, int64_t, int64_t>, std::pair<Tensor, Tensor>> rope_;
  std::map<std::tuple<int64_t, int64_t, int64_t, int64_t>, Tensor> pos_;
  std::map<std::string, LoraAdapter> lora_;
  int64_t lora_rank_ = 0;  // largest rank in lora_
  std::unique_ptr<vk::Arena> arena_;
  std::unique_ptr<BlockStream> stream_;  // the block weights, when streamed
};

}  // namespace dvs::models
