// dvs-bench realsize: the real CogVideoX-5B-I2V configuration (every width, head count, token count and
// resolution of THUDM/CogVideoX-5b-I2V, fewer repeated layers) with random bf16 weights generated on the
// device, and the host copies of those weights that the CPU references read.
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "models/weights.hpp"
#include "vk/context.hpp"

namespace dvs::bench::realsize {

// The sizes of one realsize run. "full" is the proof; "small" (DVS_REALSIZE_SCALE=small) keeps every
// width and head count but shrinks the token / frame / pixel counts (and the T5 vocabulary, whose table alone
// exceeds one binding) so the harness runs end to end while ops are still being split.
struct Scale {
  std::string name;
  int64_t t5_layers = 2, t5_vocab = 32128, prompts = 2, text_len = 226;
  int64_t transformer_layers = 1;
  int64_t latent_frames = 13, latent_height = 60, latent_width = 90;  // transformer input (13 x 60 x 90 → 17,550 + 226)
  int64_t image_height = 480, image_width = 720;                      // VAE encode / decode frame
  int64_t tile_height = 240, tile_width = 360;                        // tiled VAE calls (pixels)
  int64_t decode_latent_frames = 1;                                   // latent frames decoded
  int64_t sampled_tokens = 6;                                         // transformer tokens checked per batch row
  // DVS_REALSIZE_PROFILE=min: the calls run under the Vulkan minimum limits (vk/limit_profiles.hpp "min": 128 MiB
  // bindings, 65536-texel views, 1 GiB allocations) and its 8 GiB of device memory; unset: the device's own.
  std::string profile;
  // DVS_REALSIZE_WEIGHTS=resident|stream: T5's layers and the transformer's blocks (default: stream under a
  // profile, else resident).
  models::WeightResidency weights = models::WeightResidency::resident;
};
// DVS_REALSIZE_SCALE: unset or "full", or "small"; DVS_REALSIZE_PROFILE and DVS_REALSIZE_WEIGHTS as above.
Scale scale_from_env();
// Lowers `ctx`'s limits to the scale's profile (none: unchanged); returns a line saying what is in force.
std::string apply_profile(vk::Context& ctx, const Scale& s);

// The components' config.json contents for `scale` (the built-in real configs, with the scale's layer counts;
// the transformer's sample size follows the latent so its learned positional table is used).
nlohmann::json t5_config(const Scale& s);
nlohmann::json transformer_config(const Scale& s);
nlohmann::json vae_config(const Scale& s);

// Every tensor the config's schema lists, drawn on the device (Philox, `seed`, one stream per tensor) in f32
// chunks that fit one binding and cast to bf16: matrices and convolution kernels N(0, 1/fan_in), biases
// N(0, 0.02²), norm weights (1-D *norm*.weight) N(1, 0.05²), embeddings / positional tables N(0, 0.5²).
models::ComponentWeights random_weights(vk::Context& ctx, const nlohmann::json& config, const std::string& origin,
                                        uint64_t seed);

// f32 host copies of a component's weights, downloaded on first use (bf16 widened exactly).
class HostWeights {
 public:
  HostWeights(vk::Context& ctx, models::ComponentWeights& w) : ctx_(ctx), w_(w) {}
  const std::vector<float>& operator[](const std::string& name);
  bool has(const std::string& name) const { return all_ ? cache_.count(name) != 0 : w_.has(name); }
  // Downloads every tensor now: the weights may then move (a streamed model takes its blocks to host memory)
  // and only these copies are read.
  void load_all();

 private:
  vk::Context& ctx_;
  models::ComponentWeights& w_;
  std::map<std::string, std::vector<float>> cache_;
  bool all_ = false;
};

}  // namespace dvs::bench::realsize
