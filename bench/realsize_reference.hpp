// dvs-bench realsize: independent CPU references (fp32, OpenBLAS sgemm) of the model calls, written from the
// libraries' definitions (transformers' T5EncoderModel, diffusers' CogVideoXTransformer3DModel and
// AutoencoderKLCogVideoX), reading the same bf16 weights widened to f32 on the host.
#pragma once
#include <cstdint>
#include <vector>

#include "realsize_model.hpp"

namespace dvs::bench::realsize {

// T5 encoder, no mask: ids [B][L] -> last_hidden_state [B, L, d_model].
std::vector<float> t5_reference(HostWeights& w, const nlohmann::json& config, const std::vector<std::vector<int32_t>>& ids);

// One token of the transformer's output: batch row b, video token n (frame-major, then patch row, column).
struct TokenSample {
  int64_t b = 0, n = 0;
};
// The transformer on latent [B, F, C, H, W] / text [B, L, text_dim] / timesteps [B], for the sampled video
// tokens only (full K and V, attention for the sampled queries). rope_cos/rope_sin: the model's RoPE tables
// [N, head_dim] (inputs, as the learned positional table). Returns per sample its p·p·out_channels output
// values, in unpatchified order (c, ky, kx).
std::vector<std::vector<float>> transformer_reference(HostWeights& w, const nlohmann::json& config,
                                                      const std::vector<float>& latent, const Shape& latent_shape,
                                                      const std::vector<float>& text, int64_t text_len,
                                                      const std::vector<float>& timesteps,
                                                      const std::vector<float>& rope_cos,
                                                      const std::vector<float>& rope_sin,
                                                      const std::vector<TokenSample>& samples);

// The VAE on one frame (F = 1: every causal conv sees its input frame three times, the time rules of the
// down/up samplers reduce to spatial ones). video [1, 3, 1, H, W] -> moments [1, 2·latent, 1, H/8, W/8];
// z [1, latent, 1, h, w] -> frame [1, 3, 1, 8h, 8w].
std::vector<float> vae_encode_reference(HostWeights& w, const nlohmann::json& config, const std::vector<float>& video,
                                        int64_t height, int64_t width);
std::vector<float> vae_decode_reference(HostWeights& w, const nlohmann::json& config, const std::vector<float>& z,
                                        int64_t height, int64_t width);

}  // namespace dvs::bench::realsize
