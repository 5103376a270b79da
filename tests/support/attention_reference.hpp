// Double-precision attention reference for the attention tests: softmax(q·kᵀ·scale + bias + mask)·v with
// transformers' masking (a masked key's logit is finfo(float32).min), over operands given as host rows.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <vector>

#include "tensor/ops_attention.hpp"

namespace dvs::test::attention_ref {

using ops::AttentionShape;

inline std::vector<float> random_values(size_t n, uint32_t seed, float scale = 1.0f) {
  std::mt19937 gen(seed);
  std::normal_distribution<float> dist(0.0f, scale);
  std::vector<float> v(n);
  for (float& x : v) x = dist(gen);
  return v;
}

// Host copy of one operand: rows of `stride` floats, head h at column offset + h·D.
struct HostOperand {
  std::vector<float> data;
  int64_t offset = 0, stride = 0;
  float at(int64_t row, int64_t h, int64_t d, int64_t D) const { return data[row * stride + offset + h * D + d]; }
};

inline std::vector<double> reference(const AttentionShape& s, const HostOperand& q, const HostOperand& k,
                              const HostOperand& v, float scale, const std::vector<float>* bias,
                              const std::vector<float>* mask) {
  const int64_t D = s.head_dim, H = s.heads;
  std::vector<double> out(size_t(s.batch * s.q_len * H * D));
  std::vector<double> logit(size_t(s.kv_len));
  for (int64_t b = 0; b < s.batch; ++b)
    for (int64_t h = 0; h < H; ++h)
      for (int64_t i = 0; i < s.q_len; ++i) {
        double mx = -std::numeric_limits<double>::infinity();
        for (int64_t j = 0; j < s.kv_len; ++j) {
          double dot = 0;
          for (int64_t d = 0; d < D; ++d) dot += double(q.at(b * s.q_len + i, h, d, D)) * k.at(b * s.kv_len + j, h, d, D);
          double x = dot * scale;
          if (bias) x += (*bias)[size_t((h * s.q_len + i) * s.kv_len + j)];
          if (mask && (*mask)[size_t(b * s.kv_len + j)] == 0.0f) x = -double(std::numeric_limits<float>::max());
          logit[size_t(j)] = x;
          mx = std::max(mx, x);
        }
        double sum = 0;
        for (int64_t j = 0; j < s.kv_len; ++j) sum += (logit[size_t(j)] = std::exp(logit[size_t(j)] - mx));
        for (int64_t d = 0; d < D; ++d) {
          double acc = 0;
          for (int64_t j = 0; j < s.kv_len; ++j) acc += logit[size_t(j)] * v.at(b * s.kv_len + j, h, d, D);
          out[size_t(((b * s.q_len + i) * H + h) * D + d)] = acc / sum;
        }
      }
  return out;
}

}  // namespace dvs::test::attention_ref
