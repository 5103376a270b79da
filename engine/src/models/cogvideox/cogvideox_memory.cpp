#include "models/cogvideox/cogvideox_memory.hpp"

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "tensor/ops_attention.hpp"

namespace dvs::models {
namespace {

int64_t ceil_halvings(int64_t x, int64_t times) {
  for (int64_t i = 0; i < times; ++i) x = (x + 1) / 2;
  return x;
}

std::string shape_text(const Shape& s) {
  std::string out = "[";  // built by appends: GCC 12 warns falsely (-Wrestrict) on "[" + std::string
  out += shape_str(s);
  return out + "]";
}

int64_t max_batch(const std::vector<std::pair<int64_t, int64_t>>& batches) {
  int64_t b = 1;
  for (const auto& [start, end] : batches) b = std::max(b, end - start);
  return b;
}

// The largest activation of a VAE pass over `frames` frames (a frame batch plus the causal conv's 2 cached
// frames) at h x w pixels: each level's channels (block ℓ reads c[ℓ-1] and works at c[ℓ]) at its resolution,
// with the conv's 1-pixel padding. An upper figure at the levels that also compress time.
void consider_vae_levels(StageMemory& m, const VaeConfig& cfg, int64_t frames, int64_t h, int64_t w,
                         const std::string& what) {
  const auto& c = cfg.block_out_channels;
  for (size_t l = 0; l < c.size(); ++l) {
    const int64_t ch = std::max(c[l], c[l == 0 ? 0 : l - 1]);
    m.consider({1, ch, frames + 2, ceil_halvings(h, int64_t(l)) + 2, ceil_halvings(w, int64_t(l)) + 2}, 4,
               what + " level " + std::to_string(l) + " activation");
  }
}

}  // namespace

StageMemory t5_call_memory(const nlohmann::json& t5_config, bool embedding_16bit, uint64_t alignment, int64_t batch,
                           int64_t len, const vk::DeviceCaps* caps) {
  const auto cfg = T5EncoderConfig::from_json(t5_config);
  StageMemory m;
  m.name = "t5_encode";
  m.what = "T5 encode of " + std::to_string(batch) + " prompt(s) x " + std::to_string(len) + " tokens";
  m.working = T5Encoder::arena_bytes(cfg, embedding_16bit, alignment, batch, len);
  m.io = allocation_bytes({batch, len}, alignment) /* ids, i32 */ +
         allocation_bytes({cfg.num_heads, len, len}, alignment) /* bias */ +
         allocation_bytes({batch, len, cfg.d_model}, alignment) /* last_hidden_state */;
  // Attention scratch of the recording: a d_kv that is not a multiple of 4 is copied head-padded (under any
  // limits); split calls (under `caps`) repack K/V and carry running state.
  if (caps || cfg.d_kv % 4 != 0) {
    vk::DeviceCaps unlimited;  // no limits named: nothing splits, only the padded copies
    unlimited.max_storage_buffer_range = unlimited.max_texel_buffer_elements = 1ull << 40;
    unlimited.max_memory_allocation_size = 1ull << 50;
    unlimited.min_storage_buffer_offset_alignment = unlimited.min_texel_buffer_offset_alignment = alignment;
    for (uint32_t& g : unlimited.max_workgroup_count) g = UINT32_MAX;
    m.io += ops::attention_split_plan_fused(caps ? *caps : unlimited, {batch, cfg.num_heads, cfg.d_kv, len, len}, true)
                .scratch_bytes;
  }
  m.consider({cfg.vocab_size, cfg.d_model}, embedding_16bit ? 2 : 4, "token embedding");
  m.consider({cfg.d_ff, cfg.d_model}, embedding_16bit ? 2 : 4, "FFN weight");
  m.consider({batch, len, cfg.d_ff}, 4, "FFN activation");
  m.consider({batch, cfg.num_heads, len, len}, 4, "attention scores");
  return m;
}

StageMemory transformer_call_memory(const nlohmann::json& config, uint64_t alignment, int64_t batch, int64_t F,
                                    int64_t H, int64_t W, int64_t L, int weight_bytes, const vk::DeviceCaps* caps) {
  const auto cfg = CogVideoXTransformerConfig::from_json(config);
  const int64_t p = cfg.patch_size, N = F * (H / p) * (W / p);
  StageMemory m;
  m.name = "transformer";
  m.what = "transformer call, batch " + std::to_string(batch) + " x (" + std::to_string(L) + " + " + std::to_string(N) +
           ") tokens";
  m.working = CogVideoXTransformer::arena_bytes(cfg, alignment, batch, F, H, W, L);
  m.io = allocation_bytes({batch, F, cfg.in_channels, H, W}, alignment) +
         allocation_bytes({batch, L, cfg.text_embed_dim}, alignment) + allocation_bytes({batch}, alignment) /* timesteps */ +
         allocation_bytes({batch, F, cfg.out_channels, H, W}, alignment);
  if (cfg.rotary) m.io += 2 * allocation_bytes({N, cfg.head_dim}, alignment);                 // RoPE cos, sin
  if (cfg.learned_pos || !cfg.rotary) m.io += allocation_bytes({L + N, cfg.dim()}, alignment);  // positional table
  // Attention split over bindings: head-major K/V and running-state scratch of the recording.
  if (caps)
    m.io += ops::attention_split_plan_fused(*caps, {batch, cfg.heads, cfg.head_dim, L + N, L + N}).scratch_bytes;
  // diffusers' FeedForward: inner width 4 x dim (12288 for the 5B model).
  m.consider({cfg.dim(), 4 * cfg.dim()}, uint64_t(weight_bytes), "FFN weight");
  m.consider({batch, L + N, 3 * cfg.dim()}, 4, "q, k, v");
  m.consider({batch, L + N, 4 * cfg.dim()}, 4, "FFN activation");
  m.consider({batch, F, cfg.in_channels, H, W}, 4, "latent input");
  return m;
}

// The device peak above the weights. One frame batch: the input, the batch's working set and the result copied
// out of it (the VAE copies a result whose pool buffer is larger; an exact fit is not copied, so this is an upper
// figure), then the posterior beside the moments. Several batches: the bands copied out of the input and the
// concatenation of the per-batch results come on top. The VAE's dry run counts its buffers unpadded; the
// allocator pads small ones (GroupNorm scratch) to its alignment, a few alignments per call at most.
StageMemory vae_encode_call_memory(const nlohmann::json& config, uint64_t alignment, const Shape& video, bool posterior) {
  const VaeConfig cfg = VaeConfig::from_json(config);
  const int64_t levels = int64_t(cfg.block_out_channels.size()) - 1;
  const int64_t frames = video[2];
  const int64_t lf = frames == 1 ? 1 : (frames - 1) / cfg.temporal_compression_ratio + 1;
  const Shape moments{video[0], 2 * cfg.latent_channels, lf, ceil_halvings(video[3], levels), ceil_halvings(video[4], levels)};
  Shape half = moments;
  half[1] = cfg.latent_channels;
  StageMemory m;
  m.name = "vae_encode";
  m.what = "VAE encode of " + shape_text(video);
  m.working = CogVideoXVae::encode_working_bytes(config, video);
  const uint64_t in = allocation_bytes(video, alignment), mom = allocation_bytes(moments, alignment);
  const uint64_t post = posterior ? 2 * allocation_bytes(half, alignment) : 0;
  uint64_t total;
  if (CogVideoXVae::frame_batches(frames, 8).size() == 1) total = in + std::max(m.working + mom, mom + post);
  else total = 2 * in + m.working + 2 * mom + post;
  m.io = total - m.working;
  m.consider(video, 4, "input clip");
  m.consider(moments, 4, "moments");
  consider_vae_levels(m, cfg, max_batch(CogVideoXVae::frame_batches(frames, 8)), video[3], video[4], "encoder");
  return m;
}

// The input, the working set and the frames copied out of it, and (several latent batches) the bands and the
// concatenation, as for encode.
StageMemory vae_decode_call_memory(const nlohmann::json& config, uint64_t alignment, const Shape& z) {
  const VaeConfig cfg = VaeConfig::from_json(config);
  const int64_t r = cfg.spatial_ratio();
  const Shape frames{z[0], cfg.out_channels, (z[2] - 1) * cfg.temporal_compression_ratio + 1, z[3] * r, z[4] * r};
  StageMemory m;
  m.name = "vae_decode";
  m.what = "VAE decode of " + shape_text(z);
  m.working = CogVideoXVae::decode_working_bytes(config, z);
  const uint64_t in = allocation_bytes(z, alignment), out = allocation_bytes(frames, alignment);
  uint64_t total;
  if (CogVideoXVae::frame_batches(z[2], 2).size() == 1) total = in + m.working + out;
  else total = 2 * in + m.working + 2 * out;
  m.io = total - m.working;
  m.consider(frames, 4, "decoded frames");
  const int64_t lb = max_batch(CogVideoXVae::frame_batches(z[2], 2));
  consider_vae_levels(m, cfg, lb * cfg.temporal_compression_ratio, frames[3], frames[4], "decoder");
  return m;
}

}  // namespace dvs::models
