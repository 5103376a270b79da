// A random-weight CogVideoX-5B-I2V pipeline folder of any (small) size, in the Hugging Face layout dvs
// loads: model_index.json, scheduler/ (the real CogVideoX config), tokenizer/ (a SentencePiece unigram
// vocabulary trained on built-in captions), text_encoder/, transformer/, vae/ with config.json and
// safetensors. Weights follow the conformance pack's initialisation (fan-in scaled normals; norm weights
// 1 + N(0, 0.1²)), drawn from a seeded generator, so a seed always gives the same model. Used by
// `dvs-weights make-tiny`, `dvs demo` and tests.
#pragma once
#include <cstdint>
#include <filesystem>
#include <vector>

#include "io/dtype.hpp"

namespace dvs::models {

struct TinyModelSpec {
  uint64_t seed = 0;
  DType dtype = DType::f32;  // transformer and text encoder storage (f32 or bf16); the VAE stays f32
  // T5
  int t5_layers = 2, t5_heads = 4, t5_d_kv = 8, t5_d_model = 32, t5_d_ff = 64, vocab = 128;
  // transformer
  int layers = 2, heads = 2, head_dim = 16, time_embed_dim = 32, text_len = 8;
  int sample_frames = 9, sample_height = 8, sample_width = 8;  // latent H/W, pixel frames (pos-embedding size)
  // VAE
  std::vector<int> vae_channels = {8, 16, 16, 16};
  int vae_layers_per_block = 1, vae_groups = 4, latent_channels = 4;
};

// Writes the folder (created; existing files of the same names are replaced). Throws dvs::Error when a
// size is invalid (e.g. head_dim not a multiple of 16, channels not divisible by the group count).
void write_tiny_model(const std::filesystem::path& dir, const TinyModelSpec& spec);

}  // namespace dvs::models
