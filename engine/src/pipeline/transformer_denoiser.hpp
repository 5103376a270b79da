// The transformer as a diffusion::Denoiser: its input is concat(x, image latent) on channels, repeated for
// each CFG row, with its own activation arena sized for that batch.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "models/cogvideox/cogvideox_transformer.hpp"
#include "tensor/ops_check.hpp"
#include "tensor/tensor.hpp"
#include "vk/memory.hpp"
#include "vk/recorder.hpp"

namespace dvs {

class TransformerDenoiser {
 public:
  // image_latent [F,C,H,W]; text [batch, L, D] (uncond row first when batch = 2).
  TransformerDenoiser(vk::Context& ctx, models::CogVideoXTransformer& model, const Tensor& image_latent, const Tensor& text,
                      int batch);
  void operator()(vk::Recorder& rec, const Tensor& x, int t, const Tensor& v);
  // Scans every step's input latent and the transformer's output for NaN/Inf into `check`, in the step's own
  // recording (no extra submission); `loop` names the loop in the messages ("sampling", "inversion").
  void watch(ops::NonFiniteCheck* check, const std::string& loop) {
    check_ = check;
    loop_ = loop;
  }

 private:
  VkDeviceSize frame_bytes() const;  // one latent frame [C,H,W] in f32
  std::vector<VkBufferCopy> frame_regions(int half) const;

  vk::Context& ctx_;
  models::CogVideoXTransformer& model_;
  Tensor image_, text_, input_, timesteps_;
  int batch_;
  std::unique_ptr<vk::Arena> arena_;
  std::vector<VkBufferCopy> x_regions_;  // x into every row, per step
  ops::NonFiniteCheck* check_ = nullptr;
  std::string loop_;
  int step_ = 0;  // calls so far: the step being recorded (0-based)
};

}  // namespace dvs
