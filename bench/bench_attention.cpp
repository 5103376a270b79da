// Attention throughput: GFLOP/s counted as 4·B·H·Lq·Lk·D (q·kᵀ and p·v; the note gives TFLOP/s and the kernel
// family that ran: attention_f32 rows are the texel kernel, attention_tiled / attention_coopmat the GPU
// families, forced per row), printed next to the device FMA
// peak and OpenBLAS sgemm. Shapes: square self-attention at D = 64 over a range of heads and lengths, the
// T5-like 226-token case with relative-position bias, a fused-QKV case, and the small head dims of the
// tiny models.
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>


#include "harness.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_attention.hpp"
#include "vk/pipeline.hpp"
#include "vk/recorder.hpp"

namespace dvs::bench {
namespace {

struct Shape {
  int64_t batch, heads, len, head_dim;
  bool bias = false, fused = false, workspace = false;
  const char* family = nullptr;  // DeviceTuning::attention forced for this row (nullptr: the device's own)
};

void run_shape(Bench& b, const Shape& sh) {
  vk::Context& ctx = b.ctx();
  std::unique_ptr<ops::ScopedTuningOverride> forced;
  if (sh.family) forced = std::make_unique<ops::ScopedTuningOverride>(std::string("attention=") + sh.family);
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
  Tensor ws;
  if (sh.workspace) {
    ws = Tensor::empty(ctx, {ops::attention_workspace_elements(s)}, DType::f32);
    opt.workspace = &ws;
  }
  // The family that really runs (coopmat becomes tiled without tensor cores; bias and split calls run texel).
  const ops::KernelFamily ran = ops::attention_split_plan(ctx.caps(), s, oq, ok, ov, {out}, opt).family;
  vk::Recorder rec(ctx);
  rec.begin();
  ops::attention(rec, s, oq, ok, ov, {out}, opt);
  rec.end();
  const double flops = 4.0 * sh.batch * sh.heads * double(sh.len) * sh.len * sh.head_dim;
  const bool cpu_device = ctx.caps().type == VK_PHYSICAL_DEVICE_TYPE_CPU;
  double ms = 0, per_cpu = 0;
  if (flops > 2e10) {  // seconds per call: time a single call
    double c0 = cpu_seconds();
    auto t0 = std::chrono::steady_clock::now();
    rec.submit();
    ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    per_cpu = flops / ((cpu_seconds() - c0) * 1e9);
  } else {
    ms = Bench::time_ms([&] { rec.submit(); });
    if (cpu_device) per_cpu = gflop_per_cpu_second([&] { rec.submit(); }, flops);
  }
  char shape[96];
  std::snprintf(shape, sizeof shape, "B%lld H%lld L%lld D%lld%s%s%s", (long long)sh.batch, (long long)sh.heads,
                (long long)sh.len, (long long)sh.head_dim, sh.bias ? " bias" : "", sh.fused ? " fusedQKV" : "",
                sh.workspace ? " workspace" : "");
  std::string note = sh.bias ? "bias, scale 1 (T5)" : "no bias";
  {
    char fam[128];
    std::snprintf(fam, sizeof fam, ", %s kernel%s%s%s, %.3g TFLOP/s", ops::kernel_family_name(ran),
                  sh.family ? " (attention=" : "", sh.family ? sh.family : "", sh.family ? " forced)" : "",
                  flops / (ms * 1e9));
    note += fam;
  }
  if (sh.fused) note += ", fused QKV";
  if (sh.workspace) note += ", K/V repacked head-major (workspace)";
  if (cpu_device) {
    const double peak = b.limits().fma_peak_per_cpu_second;
    char extra[128];
    std::snprintf(extra, sizeof extra, "; %.1f GFLOP per CPU-second = %.2fx fma_peak per CPU-second", per_cpu,
                  peak > 0 ? per_cpu / peak : 0.0);
    note += extra;
  }
  const std::string op = ran == ops::KernelFamily::coopmat ? "attention_coopmat"
                         : ran == ops::KernelFamily::tiled  ? "attention_tiled"
                                                            : "attention_f32";
  b.report({op, shape, ms, flops / (ms * 1e6), 0, note});
}

void attention(Bench& b) {
  std::vector<Shape> shapes;
  if (b.quick()) {
    shapes = {{1, 2, 1024, 64}, {1, 12, 226, 64, true}, {1, 4, 512, 16}, {1, 4, 512, 6}};
  } else {
    shapes = {{1, 2, 1024, 64},
              {1, 8, 1024, 64},
              {1, 8, 1024, 64, false, false, true},
              {1, 2, 4096, 64},
              {1, 48, 2048, 64, false, true},        // the transformer's heads and fused QKV layout
              {1, 48, 2048, 64, false, true, true},  // ... with the head-major workspace
              {1, 12, 226, 64, true},                // T5-like: 226 tokens, relative bias, unscaled
              {1, 2, 1024, 128},
              {1, 4, 1024, 16},
              {1, 8, 256, 8, true},
              {1, 8, 256, 6, true},                  // a head dim not a multiple of 4 (zero-padded copies)
              {1, 2, 1024, 200},                     // a head dim over 128
              {1, 6, 2406, 64, false, true, true},   // Video-Depth-Anything Small's ViT at 518x910, one frame
              {1, 1, 17776, 64}};  // the real video sequence length, one head: memory stays O(L)
  }
  // The GPU families (shaders/nn/attention_flash*.comp), forced: on lavapipe they show what the GPU kernels
  // cost there; on a GPU, CogVideoX-5B's real size (49x480x720: B2 H48 L17776 D64, fused QKV).
  const bool cpu_device = b.ctx().caps().type == VK_PHYSICAL_DEVICE_TYPE_CPU;
  for (const char* family : {"tiled", "coopmat"}) {
    if (b.quick()) {
      shapes.push_back({1, 2, 1024, 64, false, false, false, family});
      continue;
    }
    shapes.push_back({1, 2, 1024, 64, false, false, false, family});
    shapes.push_back({1, 48, 2048, 64, false, true, false, family});
    shapes.push_back({1, 2, 1024, 128, false, false, false, family});
    if (!cpu_device) shapes.push_back({2, 48, 17776, 64, false, true, false, family});
  }
  for (const Shape& s : shapes) run_shape(b, s);
}

Registration reg("attention", 20, attention);

}  // namespace
}  // namespace dvs::bench
