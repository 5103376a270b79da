#include "models/cogvideox/cogvideox_memory.hpp"

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/cogvideox/vae_tiling.hpp"
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

}  // namespace

StageMemory t5_call_memory(const nlohmann::json& t5_config, bool embedding_16bit, uint64_t alignment, int64_t batch,
                           int64_t len, const vk::DeviceCaps* caps) {
  const auto cfg = T5EncoderConfig::from_json(t5_config);
  StageMemory m;
  m.name = "t5_encode";
  m.what = "T5 encode of " + std::to_string(batch) + " prompt(s) x " + std::to_string(len) + " tokens";
  const vk::ArenaLayout arena = T5Encoder::arena_layout(cfg, embedding_16bit, alignment, batch, len, UINT64_MAX);
  m.working = arena.bytes();
  m.consider_buffer(arena.largest, "T5 activation arena's largest tensor");
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
  m.consider({cfg.num_heads, len, len}, 4, "position bias");
  m.consider({batch, len, cfg.d_model}, 4, "last_hidden_state");
  m.consider({cfg.vocab_size, cfg.d_model}, embedding_16bit ? 2 : 4, "token embedding");
  m.consider({cfg.d_ff, cfg.d_model}, embedding_16bit ? 2 : 4, "FFN weight");
  m.consider({batch, len, cfg.d_ff}, 4, "FFN activation");
  m.consider({batch, cfg.num_heads, len, len}, 4, "attention scores");
  return m;
}

StageMemory transformer_call_memory(const nlohmann::json& config, uint64_t alignment, int64_t batch, int64_t F,
                                    int64_t H, int64_t W, int64_t L, int weight_bytes, const vk::DeviceCaps* caps) {
  const auto cfg = CogVideoXTransformerConfig::from_json(config);
  const int64_t p = cfg.patch_size, N = F * (H / p) * (W / p), S = L + N, D = cfg.dim();
  const uint64_t chunk_limit =
      caps ? std::min<uint64_t>(caps->max_storage_buffer_range, caps->max_memory_allocation_size) : UINT64_MAX;
  const int64_t chunk = CogVideoXTransformer::token_chunk(cfg, batch, S, chunk_limit);
  StageMemory m;
  m.name = "transformer";
  m.what = "transformer call, batch " + std::to_string(batch) + " x (" + std::to_string(L) + " + " + std::to_string(N) +
           ") tokens, per-token work in chunks of " + std::to_string(std::min(chunk, S)) + " tokens";
  const vk::ArenaLayout arena =
      CogVideoXTransformer::arena_layout(cfg, alignment, batch, F, H, W, L, 0, UINT64_MAX, chunk_limit);
  m.working = arena.bytes();
  m.io = allocation_bytes({batch, F, cfg.in_channels, H, W}, alignment) +
         allocation_bytes({batch, L, cfg.text_embed_dim}, alignment) + allocation_bytes({batch}, alignment) /* timesteps */ +
         allocation_bytes({batch, F, cfg.out_channels, H, W}, alignment);
  if (cfg.rotary) m.io += 2 * allocation_bytes({N, cfg.head_dim}, alignment);                 // RoPE cos, sin
  if (cfg.learned_pos || !cfg.rotary) m.io += allocation_bytes({L + N, cfg.dim()}, alignment);  // positional table
  // Attention split over bindings: the recording's scratch (Recorder::scratch) over the calls of one block, in
  // the order the chunks run. A slot keeps its buffer while requests fit and adds a larger one otherwise.
  if (caps) {
    uint64_t held[2] = {0, 0};
    auto request = [&](int slot, uint64_t bytes) {
      if (bytes <= held[slot]) return;
      held[slot] = bytes;
      m.io += align_up(std::max<uint64_t>(bytes, 16), alignment);
    };
    for (const int64_t rows : {L, N})  // the text rows' chunks, then the video rows'
      for (int64_t s0 = 0; s0 < rows; s0 += chunk) {
        const ops::AttentionSplit split = ops::attention_split_plan_contiguous(
            *caps, {batch, cfg.heads, cfg.head_dim, std::min(chunk, rows - s0), S});
        if (split.padded_head_dim > 0) {
          request(0, split.scratch_bytes);  // CogVideoX's head_dim is a multiple of 4; other configs: an upper figure
        } else {
          request(0, split.kv_scratch_request);
          request(1, split.state_scratch_request);
        }
      }
  }
  // diffusers' FeedForward: inner width 4 x dim (12288 for the 5B model).
  m.consider({cfg.dim(), 4 * cfg.dim()}, uint64_t(weight_bytes), "FFN weight");
  m.consider({batch, S, D}, 4, "residual stream / k / v");
  m.consider({batch, std::min(chunk, S), 4 * D}, 4, "FFN hidden state of one token chunk");
  m.consider({batch, F, cfg.in_channels, H, W}, 4, "latent input");
  m.consider({batch, L, cfg.text_embed_dim}, 4, "text embeddings");
  if (cfg.learned_pos || !cfg.rotary) m.consider({L + N, cfg.dim()}, 4, "positional table");
  // The arena's largest tensor as the arena places it, aligned: the figure its blocks are cut for.
  if (arena.largest > m.largest_bytes)
    m.consider_buffer(arena.largest, "activation arena's largest tensor [" + std::to_string(arena.largest / 4) + "] f32");
  return m;
}

// The device peak above the weights. One frame batch: the input, the batch's working set and the result copied
// out of it (the VAE copies a result whose pool buffer is larger; an exact fit is not copied, so this is an upper
// figure), then the posterior beside the moments. Several batches: the bands copied out of the input and the
// concatenation of the per-batch results come on top. The VAE's dry run counts its buffers unpadded; the
// allocator pads small ones (GroupNorm scratch) to its alignment, a few alignments per call at most.
// The largest buffer is the VAE's own figure (CogVideoXVae::encode_footprint: what encode checks before any
// work) or the input clip.
StageMemory vae_encode_call_memory(const nlohmann::json& config, uint64_t alignment, const Shape& video, bool posterior) {
  const VaeConfig cfg = VaeConfig::from_json(config);
  const int64_t levels = int64_t(cfg.block_out_channels.size()) - 1;
  const int64_t frames = video[2];
  const int64_t lf = frames == 1 ? 1 : (frames - 1) / cfg.temporal_compression_ratio + 1;
  const Shape moments{video[0], 2 * cfg.latent_channels, lf, ceil_halvings(video[3], levels), ceil_halvings(video[4], levels)};
  Shape half = moments;
  half[1] = cfg.latent_channels;
  const VaeFootprint f = CogVideoXVae::encode_footprint(config, video, 8, posterior);
  StageMemory m;
  m.name = "vae_encode";
  m.what = "VAE encode of " + shape_text(video);
  m.working = f.working;
  const uint64_t in = allocation_bytes(video, alignment), mom = allocation_bytes(moments, alignment);
  const uint64_t post = posterior ? 2 * allocation_bytes(half, alignment) : 0;
  uint64_t total;
  if (CogVideoXVae::frame_batches(frames, 8).size() == 1) total = in + std::max(m.working + mom, mom + post);
  else total = 2 * in + m.working + 2 * mom + post;
  m.io = total - m.working;
  m.consider(video, 4, "input clip");
  m.consider_buffer(f.largest_allocation, f.largest_what);
  return m;
}

// The frames a decode of latent z gives (4·(F−1)+1 of them, the spatial ratio up), in the VAE's layout.
static Shape decoded_shape(const VaeConfig& cfg, const Shape& z) {
  const int64_t r = cfg.spatial_ratio();
  return {z[0], cfg.out_channels, (z[2] - 1) * cfg.temporal_compression_ratio + 1, z[3] * r, z[4] * r};
}

// The input, the working set and the frames copied out of it, and (several latent batches) the bands and the
// concatenation, as for encode; the largest buffer as CogVideoXVae::decode_footprint or the latent.
StageMemory vae_decode_call_memory(const nlohmann::json& config, uint64_t alignment, const Shape& z) {
  const VaeConfig cfg = VaeConfig::from_json(config);
  const Shape frames = decoded_shape(cfg, z);
  const VaeFootprint f = CogVideoXVae::decode_footprint(config, z);
  StageMemory m;
  m.name = "vae_decode";
  m.what = "VAE decode of " + shape_text(z);
  m.working = f.working;
  const uint64_t in = allocation_bytes(z, alignment), out = allocation_bytes(frames, alignment);
  uint64_t total;
  if (CogVideoXVae::frame_batches(z[2], 2).size() == 1) total = in + m.working + out;
  else total = 2 * in + m.working + 2 * out;
  m.io = total - m.working;
  m.consider(z, 4, "latent");
  m.consider_buffer(f.largest_allocation, f.largest_what);
  return m;
}

// Tiled encode: the clip stays on the device; one tile call at a time (the largest tile's figures); the
// blended moments come back at the end with the posterior.
StageMemory vae_encode_tiled_call_memory(const nlohmann::json& config, uint64_t alignment, const Shape& video,
                                         const VaeTiling& tiling) {
  const VaeConfig cfg = VaeConfig::from_json(config);
  const TilePlan plan = TilePlan::for_encode(cfg, tiling);
  if (!(video[4] > plan.tile_in_w || video[3] > plan.tile_in_h)) return vae_encode_call_memory(config, alignment, video, true);
  const Shape tile{video[0], video[1], video[2], std::min(video[3], plan.tile_in_h), std::min(video[4], plan.tile_in_w)};
  const StageMemory one = vae_encode_call_memory(config, alignment, tile, false);
  const VaeFootprint f = CogVideoXVae::encode_tiled_footprint(config, video, tiling);
  const int64_t lf = video[2] == 1 ? 1 : (video[2] - 1) / cfg.temporal_compression_ratio + 1;
  const Shape z{video[0], cfg.latent_channels, lf, video[3] / cfg.spatial_ratio(), video[4] / cfg.spatial_ratio()};
  Shape moments = z;
  moments[1] = 2 * cfg.latent_channels;
  const int64_t tiles = ((video[3] + plan.stride_h - 1) / plan.stride_h) * ((video[4] + plan.stride_w - 1) / plan.stride_w);
  StageMemory m;
  m.name = "vae_encode";
  m.what = "VAE encode of " + shape_text(video) + " in " + std::to_string(tiles) + " tiles of " + std::to_string(tile[3]) +
           "x" + std::to_string(tile[4]);
  m.working = f.working;
  m.io = allocation_bytes(video, alignment) +
         std::max(one.total(), allocation_bytes(moments, alignment) + 2 * allocation_bytes(z, alignment)) - one.working;
  m.consider(video, 4, "input clip");
  m.consider_buffer(f.largest_allocation, f.largest_what);
  return m;
}

// Tiled decode: the latent stays; one tile call at a time; the blended frames come back whole.
StageMemory vae_decode_tiled_call_memory(const nlohmann::json& config, uint64_t alignment, const Shape& z,
                                         const VaeTiling& tiling) {
  const VaeConfig cfg = VaeConfig::from_json(config);
  const TilePlan plan = TilePlan::for_decode(cfg, tiling);
  if (!(z[4] > plan.tile_in_w || z[3] > plan.tile_in_h)) return vae_decode_call_memory(config, alignment, z);
  const Shape tile{z[0], z[1], z[2], std::min(z[3], plan.tile_in_h), std::min(z[4], plan.tile_in_w)};
  const StageMemory one = vae_decode_call_memory(config, alignment, tile);
  const VaeFootprint f = CogVideoXVae::decode_tiled_footprint(config, z, tiling);
  const Shape frames = decoded_shape(cfg, z);
  StageMemory m;
  m.name = "vae_decode";
  m.what = "VAE decode of " + shape_text(z) + " in tiles of " + std::to_string(tile[3]) + "x" + std::to_string(tile[4]) +
           " latents";
  m.working = f.working;
  m.io = allocation_bytes(z, alignment) + std::max(one.total(), allocation_bytes(frames, alignment)) - one.working;
  m.consider(z, 4, "latent");
  m.consider_buffer(f.largest_allocation, f.largest_what);
  return m;
}

}  // namespace dvs::models
