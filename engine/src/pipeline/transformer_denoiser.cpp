#include "pipeline/transformer_denoiser.hpp"

#include <vector>

#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs {

TransformerDenoiser::TransformerDenoiser(vk::Context& ctx, models::CogVideoXTransformer& model, const Tensor& image_latent,
                                         const Tensor& text, int batch)
    : ctx_(ctx), model_(model), image_(image_latent), text_(text), batch_(batch) {
  const Shape& s = image_latent.shape();  // [F, C, H, W]
  input_ = Tensor::empty(ctx, {batch, s[0], 2 * s[1], s[2], s[3]}, DType::f32, "transformer input");
  timesteps_ = Tensor::empty(ctx, {batch}, DType::f32, "timesteps");
  model.rope_tables(s[0], s[2], s[3]);
  model.positional_embedding(s[0], s[2], s[3], text.dim(1));
  arena_ = std::make_unique<vk::Arena>(ctx.allocator(), model.arena_layout(batch, s[0], s[2], s[3], text.dim(1)),
                                       "transformer activations");
  // The image half of every row never changes: written once here, so a step only copies x in (no concat).
  ops::run_now(ctx, [&](vk::Recorder& rec) { rec.copy_regions(image_.buffer(), input_.buffer(), frame_regions(1)); });
  x_regions_ = frame_regions(0);
}

// Frame f of the source ([F,C,H,W]) to the x (half 0) or image (half 1) part of frame f of every row of input_
// ([batch, F, 2C, H, W]).
std::vector<VkBufferCopy> TransformerDenoiser::frame_regions(int half) const {
  const int64_t frames = image_.dim(0);
  const VkDeviceSize bytes = frame_bytes();
  std::vector<VkBufferCopy> r;
  for (int b = 0; b < batch_; ++b)
    for (int64_t f = 0; f < frames; ++f) r.push_back({f * bytes, ((b * frames + f) * 2 + half) * bytes, bytes});
  return r;
}

VkDeviceSize TransformerDenoiser::frame_bytes() const {
  const Shape& s = image_.shape();
  return VkDeviceSize(s[1] * s[2] * s[3]) * sizeof(float);
}

void TransformerDenoiser::operator()(vk::Recorder& rec, const Tensor& x, int t, const Tensor& v) {
  std::vector<float> ts(static_cast<size_t>(batch_), static_cast<float>(t));
  timesteps_.write(ctx_, HostTensor::from_f32({batch_}, ts));  // host write before this recording runs
  rec.copy_regions(x.buffer(), input_.buffer(), x_regions_);
  arena_->reset();
  if (check_) check_->record(rec, x, loop_ + " latent entering step " + std::to_string(step_ + 1));
  model_.record(rec, *arena_, input_, text_, timesteps_, v);
  if (check_) check_->record(rec, v, "transformer output at " + loop_ + " step " + std::to_string(step_ + 1) + " (t=" + std::to_string(t) + ")");
  ++step_;
}

}  // namespace dvs
