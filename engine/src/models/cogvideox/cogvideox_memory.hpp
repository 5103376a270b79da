// Device memory of one call of each CogVideoX network, from its config.json alone (for `dvs plan` and the run's
// preflight; pipeline/memory_plan adds the calls of a run up). The activation figures are the models' own
// from-config planners (CogVideoXTransformer::arena_layout, T5Encoder::arena_layout, CogVideoXVae::*_footprint);
// this file adds the tensors each call allocates around them (inputs, outputs, tables), each rounded to the
// allocator's alignment as the allocator does, and the call's largest single tensor: for the VAE the figure
// its calls check before any work (CogVideoXVae::check_allocations), for the arenas the largest tensor placed.
#pragma once
#include <cstdint>

#include <nlohmann/json.hpp>

#include "io/host_tensor.hpp"
#include "models/call_memory.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "vk/device_info.hpp"

namespace dvs::models {

// T5 encode of `batch` prompts of `len` tokens. `caps`: the limits the call runs under (the attention's split
// scratch depends on them); none: unsplit. A d_kv that is not a multiple of 4 adds the attention's padded copies
// (ops_attention.hpp) in any case.
StageMemory t5_call_memory(const nlohmann::json& t5_config, bool embedding_16bit, uint64_t alignment, int64_t batch,
                           int64_t len, const vk::DeviceCaps* caps = nullptr);
// One transformer call of `batch` rows over a latent F x H x W and `text_len` text tokens; weight_bytes: the
// stored dtype's (the FFN weight can be the call's largest tensor); `caps` as for T5.
StageMemory transformer_call_memory(const nlohmann::json& config, uint64_t alignment, int64_t batch,
                                    int64_t latent_frames, int64_t latent_height, int64_t latent_width,
                                    int64_t text_len, int weight_bytes = 2, const vk::DeviceCaps* caps = nullptr);
// A VAE encode call of `video` [B, C, F, H, W] (encode_moments, plus the posterior when `posterior`).
StageMemory vae_encode_call_memory(const nlohmann::json& config, uint64_t alignment, const Shape& video, bool posterior);
// A VAE decode call of the latent `z` [B, Cl, Fl, Hl, Wl].
StageMemory vae_decode_call_memory(const nlohmann::json& config, uint64_t alignment, const Shape& z);
// encode_tiled / decode_tiled with `tiling` (the untiled figures where the size does not exceed the tile).
StageMemory vae_encode_tiled_call_memory(const nlohmann::json& config, uint64_t alignment, const Shape& video,
                                         const VaeTiling& tiling);
StageMemory vae_decode_tiled_call_memory(const nlohmann::json& config, uint64_t alignment, const Shape& z,
                                         const VaeTiling& tiling);

}  // namespace dvs::models
