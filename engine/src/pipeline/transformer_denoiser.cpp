#include "pipeline/transformer_denoiser.hpp"

#include <vector>

#include "tensor/ops_layout.hpp"
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
  arena_ = std::make_unique<vk::Arena>(ctx.allocator(), model.arena_bytes(batch, s[0], s[2], s[3], text.dim(1)),
                                       "transformer activations");
}

void TransformerDenoiser::operator()(vk::Recorder& rec, const Tensor& x, int t, const Tensor& v) {
  const Shape& s = image_.shape();
  std::vector<float> ts(static_cast<size_t>(batch_), static_cast<float>(t));
  timesteps_.write(ctx_, HostTensor::from_f32({batch_}, ts));  // host write before this recording runs
  Tensor row0 = input_.rows(0, 1);
  ops::concat(rec, {x.reshape({1, s[0], s[1], s[2], s[3]}), image_.reshape({1, s[0], s[1], s[2], s[3]})}, row0, 2);
  for (int b = 1; b < batch_; ++b) rec.copy(row0.buffer(), input_.rows(b, 1).buffer(), row0.bytes());
  arena_->reset();
  model_.record(rec, *arena_, input_, text_, timesteps_, v);
}

}  // namespace dvs
