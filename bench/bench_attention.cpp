// Attention throughput: GFLOP/s counted as 4·B·H·Lq·Lk·D (q·kᵀ and p·v), printed next to the device FMA
// peak and OpenBLAS sgemm. Shapes: square self-attention at D = 64 over a range of heads and lengths, the
// T5-like 226-token case with relative-position bias, a fused-QKV case, and the small head dims of the
// tiny models.
#include <cstdio>
#include <string>
#include <vector>

#include "harness.hpp"
#include "tensor/ops_attention.hpp"
#include "vk/recorder.hpp"

namespace dvs::bench {
namespace {

struct Shape {
  int64_t batch, heads, len, head_dim;
  bool bias = false, fused = false;
};

void run_shape(Bench& b, const Shape& sh) {
  vk::Context& ctx = b.ctx();
  const int64_t W = sh.heads * sh.head_dim;
  ops::AttentionShape s{sh.batch, sh.heads, sh.head_dim, sh.len, sh.len};
  Tensor qkv, q, k, v, bias;
  ops::AttentionOperand oq, ok, ov;
  if (sh.fused) {
    qkv = Tensor::zeros(ctx, {sh.batch, sh.len, 3 * W}, DType::f32);
    oq = ops::fused_qkv_operand(qkv, 0, sh.heads, sh.head_dim);
    ok = ops::fused_qkv_operand(qkv, 1, sh.heads, sh.head_dim);
    ov = ops::fused_qkv_operand(qkv, 2, sh.heads, sh.head_dim);
  } else {
    q = Tensor::zeros(ctx, {sh.batch, sh.len, W}, DType::f32);
    k = Tensor::zeros(ctx, {sh.batch, sh.len, W}, DType::f32);
    v = Tensor::zeros(ctx, {sh.batch, sh.len, W}, DType::f32);
    oq = {q};
    ok = {k};
    ov = {v};
  }
  Tensor out = Tensor::empty(ctx, {sh.batch, sh.len, W}, DType::f32);
  ops::AttentionOptions opt;
  opt.scale = sh.bias ? 1.0f : 0.125f;
  if (sh.bias) {
    bias = Tensor::zeros(ctx, {sh.heads, sh.len, sh.len}, DType::f32);
    opt.bias = &bias;
  }
  vk::Recorder rec(ctx);
  rec.begin();
  ops::attention(rec, s, oq, ok, ov, {out}, opt);
  rec.end();
  double ms = Bench::time_ms([&] { rec.submit(); });
  double flops = 4.0 * sh.batch * sh.heads * double(sh.len) * sh.len * sh.head_dim;
  char shape[96];
  std::snprintf(shape, sizeof shape, "B%lld H%lld L%lld D%lld", (long long)sh.batch, (long long)sh.heads,
                (long long)sh.len, (long long)sh.head_dim);
  std::string note = sh.bias ? "bias, scale 1 (T5)" : "no bias";
  if (sh.fused) note += ", fused QKV";
  b.report({"attention_f32", shape, ms, flops / (ms * 1e6), 0, note});
}

void attention(Bench& b) {
  std::vector<Shape> shapes;
  if (b.quick()) {
    shapes = {{1, 2, 1024, 64}, {1, 12, 226, 64, true}, {1, 4, 512, 16}};
  } else {
    shapes = {{1, 2, 1024, 64},  {1, 8, 1024, 64}, {1, 2, 4096, 64}, {1, 4, 2048, 64, false, true},
              {1, 12, 226, 64, true}, {1, 2, 1024, 128}, {1, 4, 1024, 16}, {1, 8, 256, 8, true},
              {1, 1, 17776, 64}};  // the real video sequence length, one head: memory stays O(L)
  }
  for (const Shape& s : shapes) run_shape(b, s);
}

Registration reg("attention", 20, attention);

}  // namespace
}  // namespace dvs::bench
