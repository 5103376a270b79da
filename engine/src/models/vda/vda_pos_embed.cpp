#include "models/vda/vda_pos_embed.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "dvs/error.hpp"

namespace dvs {
namespace {

constexpr float kA = -0.75f;  // PyTorch's bicubic constant

// The 4 taps and weights of one output coordinate (upsample_bicubic2d: source = scale·(dst + 0.5) - 0.5, no clamp
// at 0 for cubic; index = floor, clamped to in - 1; t clamped to [0, 1]; taps index-1 .. index+2 clamped).
struct Taps {
  std::array<int64_t, 4> index;
  std::array<float, 4> weight;
};

Taps cubic_taps(int64_t dst, int64_t in, float scale) {
  const float src = scale * (float(dst) + 0.5f) - 0.5f;
  const int64_t i = std::min<int64_t>(int64_t(std::floor(src)), in - 1);
  const float t = std::min(std::max(src - float(i), 0.0f), 1.0f);
  auto near = [](float x) { return ((kA + 2.0f) * x - (kA + 3.0f)) * x * x + 1.0f; };        // |x| <= 1
  auto far = [](float x) { return ((kA * x - 5.0f * kA) * x + 8.0f * kA) * x - 4.0f * kA; };  // 1 < |x| < 2
  Taps k;
  k.weight = {far(t + 1.0f), near(t), near(1.0f - t), far(2.0f - t)};
  for (int j = 0; j < 4; ++j) k.index[size_t(j)] = std::clamp<int64_t>(i - 1 + j, 0, in - 1);
  return k;
}

}  // namespace

HostTensor vda_resample_pos_embed(const HostTensor& table, int64_t h, int64_t w, double interpolate_offset) {
  if (table.shape.size() != 3 || table.shape[0] != 1 || table.dtype != DType::f32)
    throw Error("pos_embed must be f32 [1, 1 + M*M, D], got [" + shape_str(table.shape) + "]");
  const int64_t rows = table.shape[1] - 1, d = table.shape[2];
  const int64_t m = int64_t(std::lround(std::sqrt(double(rows))));
  if (m * m != rows) throw Error("pos_embed has " + std::to_string(rows) + " patch rows, not a square grid");
  if (h < 1 || w < 1) throw Error("pos_embed: empty patch grid " + std::to_string(h) + "x" + std::to_string(w));
  const float* src = table.as<float>();
  HostTensor out({1 + h * w, d}, DType::f32);
  float* dst = out.as<float>();
  std::copy(src, src + d, dst);  // CLS row
  if (h == m && w == m) {
    std::copy(src + d, src + (1 + rows) * d, dst + d);
    return out;
  }
  // F.interpolate with scale factors: the source scale is 1/s (in double), used as fp32.
  const float scale_h = float(1.0 / ((double(h) + interpolate_offset) / double(m)));
  const float scale_w = float(1.0 / ((double(w) + interpolate_offset) / double(m)));
  std::vector<Taps> ty(static_cast<size_t>(h)), tx(static_cast<size_t>(w));
  for (int64_t y = 0; y < h; ++y) ty[size_t(y)] = cubic_taps(y, m, scale_h);
  for (int64_t x = 0; x < w; ++x) tx[size_t(x)] = cubic_taps(x, m, scale_w);
  // Separable, rows outside, in PyTorch's order: out = Σ_j wy_j · (Σ_i wx_i · in[y_j, x_i]), sums left to right.
  for (int64_t y = 0; y < h; ++y)
    for (int64_t x = 0; x < w; ++x)
      for (int64_t c = 0; c < d; ++c) {
        auto at = [&](int64_t r, int64_t col) { return src[(1 + r * m + col) * d + c]; };
        float acc = 0.0f;
        for (int j = 0; j < 4; ++j) {
          const int64_t r = ty[size_t(y)].index[size_t(j)];
          float row = at(r, tx[size_t(x)].index[0]) * tx[size_t(x)].weight[0];
          for (int i = 1; i < 4; ++i) row += at(r, tx[size_t(x)].index[size_t(i)]) * tx[size_t(x)].weight[size_t(i)];
          acc = j == 0 ? row * ty[size_t(y)].weight[0] : acc + row * ty[size_t(y)].weight[size_t(j)];
        }
        dst[(1 + y * w + x) * d + c] = acc;
      }
  return out;
}

}  // namespace dvs
