// Convolutions (compute-bound: GFLOP/s, 2 flops per multiply-add) and resampling (memory-bound: GB/s of
// bytes read + written) at VAE-like shapes. Each op is recorded once and the recording is replayed.
#include <cmath>
#include <string>
#include <vector>

#include "harness.hpp"
#include "tensor/ops_conv.hpp"
#include "vk/recorder.hpp"

namespace dvs::bench {
namespace {

Tensor filled(vk::Context& ctx, const Shape& s, DType dt, float scale) {
  HostTensor h(s, dt);
  uint32_t state = 12345;
  for (int64_t i = 0; i < h.numel(); ++i) {
    state = state * 1664525u + 1013904223u;
    float v = (float(state >> 8) / float(1u << 24) * 2.f - 1.f) * scale;
    if (dt == DType::f32) h.as<float>()[i] = v;
    else if (dt == DType::bf16) h.as<uint16_t>()[i] = f32_to_bf16(v);
    else h.as<uint16_t>()[i] = f32_to_f16(v);
  }
  return Tensor::upload(ctx, h);
}

// Times replays of one recording; big convs get fewer repeats so the group stays within a minute or two.
double time_recording(Bench& b, const std::function<void(vk::Recorder&)>& record, double min_seconds = 0.5) {
  vk::Recorder rec(b.ctx());
  rec.begin();
  record(rec);
  rec.end();
  return Bench::time_ms([&] { rec.submit(); }, min_seconds);
}

void conv3d(Bench& b, int64_t cin, int64_t cout, int64_t f, int64_t h, int64_t w, DType wdt, bool cached) {
  vk::Context& ctx = b.ctx();
  Tensor x = filled(ctx, {1, cin, f, h, w}, DType::f32, 1.f);
  Tensor wt = filled(ctx, {cout, cin, 3, 3, 3}, wdt, 0.05f);
  Tensor bias = filled(ctx, {cout}, wdt, 0.1f);
  Tensor y = Tensor::empty(ctx, {1, cout, f, h, w}, DType::f32);
  Tensor cache = filled(ctx, {1, cin, 2, h, w}, DType::f32, 1.f);
  double ms = time_recording(b, [&](vk::Recorder& rec) {
    ops::causal_conv3d(rec, x, wt, &bias, y, cached ? &cache : nullptr, cached ? &cache : nullptr);
  }, 0.2);
  double flops = 2.0 * double(cout) * double(cin) * 27.0 * double(f * h * w);
  std::string shape = std::to_string(cin) + "->" + std::to_string(cout) + " " + std::to_string(f) + "x" +
                      std::to_string(h) + "x" + std::to_string(w);
  b.report({std::string("causal_conv3d_3x3x3_") + dtype_name(wdt), shape, ms, flops / (ms * 1e6), 0,
            cached ? "with cache in/out" : "first batch"});
}

void conv2d(Bench& b, const char* name, int64_t cin, int64_t cout, int64_t f, int64_t h, int64_t w, int64_t k,
            const ops::Conv2dParams& p, DType wdt) {
  vk::Context& ctx = b.ctx();
  Tensor x = filled(ctx, {1, cin, f, h, w}, DType::f32, 1.f);
  Tensor wt = filled(ctx, {cout, cin, k, k}, wdt, 0.05f);
  Tensor bias = filled(ctx, {cout}, wdt, 0.1f);
  Shape ys = ops::conv2d_shape(x.shape(), wt.shape(), p);
  Tensor y = Tensor::empty(ctx, ys, DType::f32);
  double ms = time_recording(b, [&](vk::Recorder& rec) { ops::conv2d(rec, x, wt, &bias, y, p); }, 0.3);
  double outputs = double(shape_numel(ys)) / double(cout);
  double flops = 2.0 * double(cout) * double(cin * k * k) * outputs;
  std::string shape = std::to_string(cin) + "->" + std::to_string(cout) + " " + std::to_string(f) + "x" +
                      std::to_string(h) + "x" + std::to_string(w);
  b.report({std::string(name) + "_" + dtype_name(wdt), shape, ms, flops / (ms * 1e6), 0, ""});
}

void conv1x1(Bench& b, int64_t cin, int64_t cout, int64_t f, int64_t h, int64_t w) {
  vk::Context& ctx = b.ctx();
  Tensor x = filled(ctx, {1, cin, f, h, w}, DType::f32, 1.f);
  Tensor wt = filled(ctx, {cout, cin, 1, 1, 1}, DType::bf16, 0.05f);
  Tensor y = Tensor::empty(ctx, {1, cout, f, h, w}, DType::f32);
  double ms = time_recording(b, [&](vk::Recorder& rec) { ops::conv1x1(rec, x, wt, nullptr, y); }, 0.3);
  double flops = 2.0 * double(cout) * double(cin) * double(f * h * w);
  b.report({"conv1x1_bf16", std::to_string(cin) + "->" + std::to_string(cout) + " " + std::to_string(f) + "x" +
                                std::to_string(h) + "x" + std::to_string(w),
            ms, flops / (ms * 1e6), 0, ""});
}

// CogVideoXUpsample3D (compress_time): upsample2x + conv 3x3 fused, next to the two ops run separately.
void upsample_conv(Bench& b, int64_t c, int64_t f, int64_t h, int64_t w) {
  vk::Context& ctx = b.ctx();
  Tensor x = filled(ctx, {1, c, f, h, w}, DType::f32, 1.f);
  Tensor wt = filled(ctx, {c, c, 3, 3}, DType::bf16, 0.05f);
  Tensor bias = filled(ctx, {c}, DType::bf16, 0.1f);
  Shape us = ops::upsample2x_shape(x.shape(), true);
  Tensor u = Tensor::empty(ctx, us, DType::f32);
  Tensor y = Tensor::empty(ctx, {us[0], c, us[2], us[3], us[4]}, DType::f32);
  double flops = 2.0 * double(c) * double(c * 9) * double(us[2] * us[3] * us[4]);
  std::string shape = std::to_string(c) + "->" + std::to_string(c) + " " + std::to_string(f) + "x" + std::to_string(h) +
                      "x" + std::to_string(w) + " -> " + std::to_string(us[2]) + "x" + std::to_string(us[3]) + "x" +
                      std::to_string(us[4]);
  double fused = time_recording(b, [&](vk::Recorder& rec) { ops::upsample2x_conv3x3(rec, x, wt, &bias, y, true); }, 0.2);
  b.report({"upsample2x_conv3x3_fused_bf16", shape, fused, flops / (fused * 1e6), 0, "CogVideoXUpsample3D"});
  double split = time_recording(b, [&](vk::Recorder& rec) {
    ops::upsample2x(rec, x, u, true);
    ops::conv2d(rec, u, wt, &bias, y, ops::Conv2dParams::same3x3());
  }, 0.2);
  b.report({"upsample2x_then_conv3x3_bf16", shape, split, flops / (split * 1e6), 0, "two ops, upsampled tensor stored"});
}

void resampling(Bench& b, int64_t c, int64_t f, int64_t h, int64_t w) {
  vk::Context& ctx = b.ctx();
  std::string dims = std::to_string(c) + "x" + std::to_string(f) + "x" + std::to_string(h) + "x" + std::to_string(w);
  {
    Tensor x = filled(ctx, {1, c, f, h, w}, DType::f32, 1.f);
    Tensor y = Tensor::empty(ctx, {1, c, ops::downsample_time_frames(f), h, w}, DType::f32);
    double ms = time_recording(b, [&](vk::Recorder& rec) { ops::avgpool_time_pairs(rec, x, y); });
    b.report({"avgpool_time_pairs", dims, ms, 0, double(x.bytes() + y.bytes()) / (ms * 1e6), ""});
  }
  {
    int64_t fl = (f - 1) / 4 + 1;  // a latent-like frame count (odd)
    Tensor x = filled(ctx, {1, c, fl, h / 2, w / 2}, DType::f32, 1.f);
    Tensor y = Tensor::empty(ctx, ops::upsample2x_shape(x.shape(), true), DType::f32);
    double ms = time_recording(b, [&](vk::Recorder& rec) { ops::upsample2x(rec, x, y, true); });
    b.report({"upsample2x_time", std::to_string(c) + "x" + std::to_string(fl) + "x" + std::to_string(h / 2) + "x" +
                                     std::to_string(w / 2),
              ms, 0, double(x.bytes() + y.bytes()) / (ms * 1e6), "compress_time"});
  }
}

void conv_group(Bench& b) {
  bool q = b.quick();
  // VAE-like causal conv3d: 128 channels, a 9-frame batch at 60x90 (the 480x720 encoder at 1/8 scale).
  conv3d(b, 128, 128, q ? 3 : 9, 60, 90, DType::bf16, false);
  conv3d(b, 128, 128, 3, 60, 90, DType::f32, true);
  conv3d(b, 3, 128, 3, 60, 90, DType::bf16, false);  // conv_in: few input channels
  conv2d(b, "conv2d_3x3", 128, 128, 1, 60, 90, 3, ops::Conv2dParams::same3x3(), DType::bf16);
  conv2d(b, "conv2d_3x3_s2_down", 128, 128, 1, 120, 180, 3, ops::Conv2dParams::downsample3x3(), DType::bf16);
  conv2d(b, "conv2d_patch_2x2", 32, 3072, 1, 60, 90, 2, ops::Conv2dParams::patch(true), DType::bf16);
  conv1x1(b, 128, 256, 3, 60, 90);
  upsample_conv(b, 128, 3, 30, 45);
  resampling(b, 128, 9, 120, 180);
}

Registration reg("conv", 10, conv_group);

}  // namespace
}  // namespace dvs::bench

