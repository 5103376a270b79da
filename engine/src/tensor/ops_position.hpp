// Positional encodings: 3D rotary embedding (tables built on the host exactly as diffusers' CogVideoX
// pipelines do, applied by a shader to a slice of tokens) and the sinusoidal timestep embedding.
#pragma once
#include <cstdint>

#include "io/host_tensor.hpp"
#include "tensor/dispatch.hpp"

namespace dvs::ops {

// Rotary tables for CogVideoX 1.0 (patch_size_t unset), as CogVideoXImageToVideoPipeline.
// _prepare_rotary_positional_embeddings -> get_3d_rotary_pos_embed (linspace grid, use_real, theta 1e4):
// rows = video tokens in (frame, row, column) order, columns = head_dim laid out [t (Dh/4) | h (3Dh/8) |
// w (3Dh/8)], each frequency repeated twice. Computed in fp32 as torch does on the CPU.
struct RopeTables {
  HostTensor cos, sin;  // f32 [frames*grid_h*grid_w, head_dim]
};
// grid_h/grid_w: token grid (latent size / patch size); base_h/base_w: sample_height/width // patch size.
RopeTables cogvideox_rope_tables(int64_t head_dim, int64_t frames, int64_t grid_h, int64_t grid_w, int64_t base_h,
                                 int64_t base_w);
// Same, from the pipeline's arguments: pixel height/width, latent frames, VAE spatial factor (8), and the
// transformer config's patch_size, sample_height, sample_width, attention_head_dim.
RopeTables cogvideox_rope_tables_for_video(int64_t height, int64_t width, int64_t latent_frames,
                                           int64_t vae_scale_spatial, int64_t patch_size, int64_t sample_height,
                                           int64_t sample_width, int64_t head_dim);

// Applies RoPE in interleaved pairs to tokens [first, first+n) of every batch: x is [B*L, row_stride] (f32)
// holding heads*head_dim columns from col_offset (q or k inside a fused QKV output; q and k side by side
// can be done at once as 2*heads heads). cos/sin: f32 [n, head_dim], shared by heads. y has x's shape and
// layout and may be x; outside the slice y is not written.
void rope(vk::Recorder& rec, const Tensor& x, const Tensor& y, int64_t batch, int64_t seq_len, int64_t first,
          int64_t heads, int64_t head_dim, int64_t col_offset, const Tensor& cos, const Tensor& sin);

// Sinusoidal timestep embedding (diffusers get_timestep_embedding): timesteps f32 [B] -> emb f32 [B, D].
// CogVideoX: flip_sin_to_cos = true ([cos | sin]), freq_shift = 0, scale = 1.
void timestep_embedding(vk::Recorder& rec, const Tensor& timesteps, const Tensor& emb, bool flip_sin_to_cos = true,
                        float freq_shift = 0.0f, float scale = 1.0f);

}  // namespace dvs::ops
