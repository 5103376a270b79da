// Every convolution path of the VAE as a list of calls, for tests that compare one setting against another on all
// of them: causal 3x3x3 without and with a cache, 3x3, the stride-2 downsample, 1x1 and the fused x2 upsample.
// x [B, Cin, F, H, W] and cache [B, Cin, 2, H, W] f32; w3 [Cout, Cin, 3, 3, 3], w2 [Cout, Cin, 3, 3], w1
// [Cout, Cin, 1, 1, 1] (stored or packed, ops_conv_weights.hpp); b [Cout]. x, cache, b and the tensors the weights
// view must outlive the calls (the weight views themselves are copied into them).
#pragma once
#include <functional>
#include <string>
#include <vector>

#include "tensor/ops_conv.hpp"

namespace dvs::test {

struct VaeConvPath {
  std::string name;
  Shape out;  // y's shape
  std::function<void(vk::Recorder&, const Tensor& y)> call;
};

inline std::vector<VaeConvPath> vae_conv_paths(const Tensor& x, const Tensor& cache, const ops::ConvWeights& w3,
                                               const ops::ConvWeights& w2, const ops::ConvWeights& w1, const Tensor& b) {
  const int64_t cout = w3.dim(0);
  Shape y = x.shape();
  y[1] = cout;
  const Shape down = ops::conv2d_shape(x.shape(), w2.shape(), ops::Conv2dParams::downsample3x3());
  Shape up = ops::upsample2x_shape(x.shape(), true);
  up[1] = cout;
  return {
      {"causal conv", y, [&x, &b, w3](vk::Recorder& rec, const Tensor& o) { ops::causal_conv3d(rec, x, w3, &b, o); }},
      {"causal conv with cache", y, [&x, &b, &cache, w3](vk::Recorder& rec, const Tensor& o) {
         ops::causal_conv3d(rec, x, w3, &b, o, &cache);
       }},
      {"conv2d 3x3", y, [&x, &b, w2](vk::Recorder& rec, const Tensor& o) { ops::conv2d(rec, x, w2, &b, o, ops::Conv2dParams::same3x3()); }},
      {"downsample 3x3 s2", down,
       [&x, w2](vk::Recorder& rec, const Tensor& o) { ops::conv2d(rec, x, w2, nullptr, o, ops::Conv2dParams::downsample3x3()); }},
      {"conv 1x1", y, [&x, w1](vk::Recorder& rec, const Tensor& o) { ops::conv1x1(rec, x, w1, nullptr, o); }},
      {"upsample x2 + conv 3x3", up, [&x, &b, w2](vk::Recorder& rec, const Tensor& o) { ops::upsample2x_conv3x3(rec, x, w2, &b, o, true); }},
  };
}

}  // namespace dvs::test
