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
#include "tensor/tensor.hpp"
#include "vk/context.hpp"

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

// Random q, k, v for `s` on the host and the device: fused (column slices of one [B, L, 3·H·D] tensor; needs
// Lq == Lk) or three [B, L, H·D + 2·pad] tensors holding their operand at column `pad`. Seeds: one for the
// fused tensor, else seed, seed + 1, seed + 2.
struct Operands {
  HostOperand hq, hk, hv;
  ops::AttentionOperand q, k, v;
};

inline Operands random_operands(vk::Context& ctx, const AttentionShape& s, bool fused, int64_t pad, uint32_t seed) {
  const int64_t W = s.heads * s.head_dim;
  Operands o;
  if (fused) {
    std::vector<float> all = random_values(size_t(s.batch * s.q_len * 3 * W), seed);
    o.hq = {all, 0, 3 * W};
    o.hk = {all, W, 3 * W};
    o.hv = {all, 2 * W, 3 * W};
    const Tensor qkv = Tensor::upload(ctx, HostTensor::from_f32({s.batch, s.q_len, 3 * W}, all));
    o.q = ops::fused_qkv_operand(qkv, 0, s.heads, s.head_dim);
    o.k = ops::fused_qkv_operand(qkv, 1, s.heads, s.head_dim);
    o.v = ops::fused_qkv_operand(qkv, 2, s.heads, s.head_dim);
    return o;
  }
  const int64_t stride = W + 2 * pad;
  auto make = [&](int64_t len, uint32_t sd, HostOperand& h, ops::AttentionOperand& op) {
    h = {random_values(size_t(s.batch * len * stride), sd), pad, stride};
    op = {Tensor::upload(ctx, HostTensor::from_f32({s.batch, len, stride}, h.data)), pad, stride};
  };
  make(s.q_len, seed, o.hq, o.q);
  make(s.kv_len, seed + 1, o.hk, o.k);
  make(s.kv_len, seed + 2, o.hv, o.v);
  return o;
}

}  // namespace dvs::test::attention_ref
