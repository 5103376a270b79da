// Video-Depth-Anything (DINOv2 ViT encoder + DPT head with four temporal modules) as GLSL compute: one forward of
// a window of T frames [T, 3, H, W] (H, W multiples of the patch size, ImageNet-normalised) to disparity [T, H, W].
// Exact to github:DepthAnything/Video-Depth-Anything (see tests/golden/vda-A/README.md for every detail).
//
// Layouts inside: frames in the batch ("BT"); ViT tokens [BT, 1 + h*w, D]; head feature maps [BT, C, H, W];
// a temporal module works on [B, H*W, T, C] (one sequence of T frames per spatial position), so its LayerNorms,
// Linears, attention and the position table's broadcast all run on contiguous rows.
// Every stage records into its own submission (bounded work per submission) and its temporaries are freed after.
#pragma once
#include <array>
#include <filesystem>
#include <functional>
#include <map>
#include <string>

#include "spec/vda_config.hpp"
#include "tensor/ops_conv_weights.hpp"
#include "tensor/tensor.hpp"
#include "vk/context.hpp"

namespace dvs {

class VdaModel {
 public:
  // Reads the checkpoint through the weight loader (io/weight_set.hpp: a .pth or a safetensors file, e.g. one written
  // by `dvs-weights convert`, told apart by content whatever its extension), resolves its architecture
  // (config.json beside it, else the released sizes) and uploads every tensor. Throws dvs::Error naming the file.
  static VdaModel load(vk::Context& ctx, const std::filesystem::path& checkpoint);
  // The architecture alone, from the tensors' names and shapes (no weights read): a cheap check before long work.
  static VdaConfig inspect(const std::filesystem::path& checkpoint);
  // Whether load() keeps tensor `name` packed for the conv kernels (ops_conv_weights.hpp: the patch embedding, the
  // DPT head's stride-2 resize and scratch convs; the head's 1x1 projections run as Linears and stay as stored).
  static bool packs_as_conv(const std::string& name, const Shape& shape);

  const VdaConfig& config() const { return cfg_; }
  vk::Context& context() const { return *ctx_; }
  // Metric mode (no scale/shift alignment between windows): recognised from the released metric checkpoints'
  // file names or a config's inference.metric; this overrides it.
  void set_metric(bool metric) { cfg_.metric = metric; }
  uint64_t weight_bytes() const { return weight_bytes_; }

  // Called with named intermediates (the conformance pack's file stems, e.g. "encoder/block0", "head/layer1",
  // "temporal/m0_attn0_q") after their stage has run; tests compare them. Unset: nothing extra is computed.
  using Probe = std::function<void(const std::string& name, const Tensor& t)>;
  void set_probe(Probe p) { probe_ = std::move(p); }

  // Frames per pass through the head's full-resolution stages (refinenet2 on); 0 = all at once. The reference
  // uses 4; 2 halves that stage's memory (~0.7 GiB for vits at 518x784); the value changes memory, never results.
  void set_micro_batch(int frames) { micro_batch_ = frames; }
  static constexpr int kHeadMicroBatch = 2;
  // Spatial positions per pass through a temporal module's block (0 = as many as fit kTemporalChunkBytes); the
  // value changes memory, never results. Tests force small chunks.
  void set_temporal_chunk_positions(int64_t positions) { temporal_chunk_positions_ = positions; }
  static constexpr int64_t kTemporalChunkBytes = int64_t(64) << 20;
  // Frames per pass through the ViT encoder (frames are independent there); changes memory, never results.
  void set_encoder_chunk_frames(int64_t frames) { encoder_chunk_frames_ = frames; }
  static constexpr int64_t kEncoderChunkFrames = 4;

  // Called inside forward() after every encoder block of every frame chunk and every head stage (temporal
  // modules, full-resolution chunks) with what ran and how far the forward is (done of total): progress within a
  // window, and a place to stop (it may throw dvs::Cancelled). Unset: nothing is called.
  using StepHook = std::function<void(const std::string& what, int done, int total)>;
  void set_step_hook(StepHook hook) { step_hook_ = std::move(hook); }

  // x: f32 [T, 3, H, W] -> disparity f32 [T, H, W] (>= 0), H and W multiples of the patch size.
  Tensor forward(const Tensor& x);

  // The stages, for tests and for the long-video driver.
  std::array<Tensor, 4> encode(const Tensor& x);                                  // taps [BT, h*w, D]
  Tensor temporal(int module, const Tensor& x, int64_t frames);                   // [BT, C, H, W] -> same
  Tensor head(std::array<Tensor, 4> taps, int64_t h, int64_t w, int64_t frames);  // -> [BT, 1, 14h, 14w]; frees the taps

 private:
  VdaModel(vk::Context& ctx, VdaConfig cfg) : ctx_(&ctx), cfg_(std::move(cfg)) {}
  const Tensor& w(const std::string& name) const;
  const ops::PackedConvWeights& conv_weights(const std::string& name) const;  // packed at load
  void probe(const std::string& name, const Tensor& t) const {
    if (probe_) probe_(name, t);
  }
  Tensor vit_block(int index, const Tensor& x, int64_t frames, int64_t tokens);
  Tensor reassemble(int index, const Tensor& tap, int64_t h, int64_t w);
  Tensor conv(const std::string& prefix, const Tensor& x, int stride, int pad, bool bias);
  Tensor residual_conv_unit(const std::string& prefix, const Tensor& x);
  Tensor fusion(int index, const Tensor& x0, const Tensor* x1, int64_t out_h, int64_t out_w);
  const Tensor& pos_embed(int64_t h, int64_t w);

  vk::Context* ctx_;
  VdaConfig cfg_;
  std::filesystem::path file_;
  std::map<std::string, Tensor> weights_;
  std::map<std::string, ops::PackedConvWeights> conv_weights_;  // the convolutions' (load())
  std::map<std::pair<int64_t, int64_t>, Tensor> pos_embed_;  // resampled tables per patch grid
  HostTensor pos_table_;
  uint64_t weight_bytes_ = 0;
  Probe probe_;
  void step(const std::string& what);
  StepHook step_hook_;
  int steps_done_ = 0, steps_total_ = 0;  // of the forward() in progress
  int micro_batch_ = kHeadMicroBatch;
  int64_t temporal_chunk_positions_ = 0;
  int64_t encoder_chunk_frames_ = kEncoderChunkFrames;
};

}  // namespace dvs
