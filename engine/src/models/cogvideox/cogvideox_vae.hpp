// CogVideoX 3D causal VAE (diffusers AutoencoderKLCogVideoX), built from the kernel library.
// Layout B,C,F,H,W, f32 activations; weights in their stored dtype. Every size comes from the vae/config.json.
//
// Frame batching is diffusers' exactly: encode runs frames [0 : 8+r] then 8 at a time (r = F mod 8; 9 -> one
// batch, 17 -> [0:9],[9:17]); decode runs latent frames [0 : 2+r] then 2 at a time (r = Fl mod 2). Each
// batch is one recording; GroupNorm statistics are per batch; every causal conv (kt = 3) carries its last
// two padded input frames to the next batch (the conv cache).
//
// Latents here are in VAE units. The diffusion latent is scaling_factor * VAE latent (0.7 for CogVideoX-5B);
// to_diffusion_latent / from_diffusion_latent do that scaling, the caller decides where.
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "models/weights.hpp"
#include "spec/cogvideox_config.hpp"
#include "tensor/tensor.hpp"

namespace dvs::vk {
class Context;
class Recorder;
}  // namespace dvs::vk

namespace dvs::models {

using dvs::VaeConfig;  // spec/cogvideox_config.hpp

// diffusers' enable_tiling() settings. Defaults: tiles of half the config's sample size, overlap 1/6 (H), 1/5 (W).
struct VaeTiling {
  int64_t tile_sample_min_height = 0, tile_sample_min_width = 0;  // 0: sample_height / 2, sample_width / 2
  double tile_overlap_factor_height = 1.0 / 6.0, tile_overlap_factor_width = 1.0 / 5.0;
};

// The posterior in VAE units: mean and std [B, Cl, Fl, Hl, Wl]; moments = concat(mean, raw logvar) on C.
struct VaePosterior {
  Tensor moments, mean, std;
};

// Memory of one VAE call from its working-set planner (CogVideoXVae::*_footprint): `working` is the largest
// working set of one frame batch in bytes (every intermediate buffer plus the conv caches, as
// *_working_bytes); `largest_tensor` is the largest single buffer among them (an activation, a convolution's
// staging, a conv cache). `largest_allocation` is the largest single buffer the whole call allocates: those,
// the frame bands it copies out of its input, its result and (encode) the posterior; for a tiled call also
// each tile's upload and the blended result's; `largest_what` names it. That figure is the one
// check_allocations holds against maxMemoryAllocationSize before any work, and the one `dvs plan` and the
// preflight report for the call (each buffer is one allocation; every binding of it is split to the device's
// limits by the ops themselves, tensor/ops_conv.hpp). Not counted: weights and the call's input.
struct VaeFootprint {
  uint64_t working = 0, largest_tensor = 0;
  uint64_t largest_allocation = 0;
  std::string largest_what;
};

class CogVideoXVae {
 public:
  CogVideoXVae(vk::Context& ctx, const std::filesystem::path& vae_dir);
  // From weights already on the device (ComponentWeights' in-memory constructor; benchmarks).
  CogVideoXVae(vk::Context& ctx, ComponentWeights weights);
  ~CogVideoXVae();

  const VaeConfig& config() const { return cfg_; }
  ComponentWeights& weights() { return weights_; }

  // Frame batch sizes (diffusers' num_sample_frames_batch_size / num_latent_frames_batch_size).
  int64_t sample_frames_batch = 8, latent_frames_batch = 2;

  // video [B, in_channels, F, H, W] f32 in [-1, 1] -> posterior [B, Cl, Fl, ceil-halved H, W per down block].
  // Any F (diffusers expects 1, 8k or 8k+1) and any H, W; not tiled.
  VaePosterior encode(const Tensor& video);
  // z [B, latent_channels, Fl, Hl, Wl] f32 in VAE units -> frames [B, out_channels, F, H, W]. Not tiled.
  Tensor decode(const Tensor& z);

  // diffusers' tiled_encode / tiled_decode (tiles blended on the host; used when the size exceeds the tile,
  // otherwise these fall back to encode / decode as diffusers does).
  VaePosterior encode_tiled(const Tensor& video, const VaeTiling& tiling);
  Tensor decode_tiled(const Tensor& z, const VaeTiling& tiling);

  // Scaling between VAE units and the diffusion latent (y may be x).
  void to_diffusion_latent(vk::Recorder& rec, const Tensor& z, const Tensor& y) const;    // y = s·z
  void from_diffusion_latent(vk::Recorder& rec, const Tensor& x, const Tensor& z) const;  // z = x / s
  // A posterior sample in VAE units, as DiagonalGaussianDistribution.sample: out = mean + std·noise (noise
  // standard normal, caller-drawn, of mean's shape; out may be noise).
  static void sample(vk::Recorder& rec, const VaePosterior& p, const Tensor& noise, const Tensor& out);

  // Frame ranges [start, end) of the batches diffusers uses for `frames` frames and batch size `batch`.
  static std::vector<std::pair<int64_t, int64_t>> frame_batches(int64_t frames, int64_t batch);

  // Memory planning from config.json alone (no weights, no device): the largest working set of one frame
  // batch — every intermediate buffer of that batch plus the conv caches, in bytes — of encode(video shape)
  // or decode(z shape). Not counted: weights, the call's input and its result (moments / frames), and the
  // posterior. For a tiled call pass the tile's shape. It is exactly what a live call allocates
  // (last_working_bytes() after it).
  static uint64_t encode_working_bytes(const nlohmann::json& config, const Shape& video, int64_t frames_batch = 8);
  static uint64_t decode_working_bytes(const nlohmann::json& config, const Shape& z, int64_t latent_batch = 2);
  uint64_t last_working_bytes() const { return last_peak_bytes_; }
  // The same plans with the call's largest allocations too: encode(video) (with the posterior; without it,
  // `posterior` false, as encode_tiled runs each tile), decode(z), and the tiled calls for `tiling` (every
  // distinct tile shape; the untiled figures where the size does not exceed the tile, as those calls fall
  // back). The calls themselves check these figures (check_allocations) and `dvs plan` reports them: one
  // estimate. A live call's working set and largest buffer are last_footprint() after it.
  static VaeFootprint encode_footprint(const nlohmann::json& config, const Shape& video, int64_t frames_batch = 8,
                                       bool posterior = true);
  static VaeFootprint decode_footprint(const nlohmann::json& config, const Shape& z, int64_t latent_batch = 2);
  static VaeFootprint encode_tiled_footprint(const nlohmann::json& config, const Shape& video, const VaeTiling& tiling,
                                             int64_t frames_batch = 8);
  static VaeFootprint decode_tiled_footprint(const nlohmann::json& config, const Shape& z, const VaeTiling& tiling,
                                             int64_t latent_batch = 2);
  VaeFootprint last_footprint() const { return last_footprint_; }

 private:
  Tensor encode_moments(const Tensor& video);
  Tensor run_frame_batches(const Tensor& x, int64_t frames_batch, bool decoder, const char* name);
  VaePosterior posterior_of(const Tensor& moments);
  void check_allocations(const char* what, const VaeFootprint& f) const;

  vk::Context& ctx_;
  ComponentWeights weights_;
  VaeConfig cfg_;
  uint64_t last_peak_bytes_ = 0;
  VaeFootprint last_footprint_;
};

}  // namespace dvs::models
