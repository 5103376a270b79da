// Convolutions (compute-bound: GFLOP/s, 2 flops per multiply-add) at the CogVideoX VAE's shapes, each
// next to the device's FMA peak measured right before it and to the CPU's own limit for the same
// convolution (OpenBLAS sgemm over an im2col buffer, on OPENBLAS_NUM_THREADS threads, in the same run);
// resampling (memory-bound: GB/s); and group "conv_vae": a whole VAE encode and decode at a fixed size,
// in seconds per frame. On a CPU device the machine is usually shared: the ratio per CPU-second (conv and
// peak both measured as work per CPU-second of this process) is the figure that survives other load.
// DVS_BENCH_CONV_TILE tries a register block, DVS_BENCH_CONV_LOOP keeps one shape running for a profiler.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include "harness.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/random/tiny_model.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv.hpp"
#include "vk/recorder.hpp"

#ifdef DVS_HAVE_BLAS
extern "C" void sgemm_(const char* ta, const char* tb, const int* m, const int* n, const int* k, const float* alpha,
                       const float* a, const int* lda, const float* b, const int* ldb, const float* beta, float* c,
                       const int* ldc);
#endif

namespace dvs::bench {
namespace {

float lcg_value(uint32_t& state, float scale) {
  state = state * 1664525u + 1013904223u;
  return (float(state >> 8) / float(1u << 24) * 2.f - 1.f) * scale;
}

Tensor filled(vk::Context& ctx, const Shape& s, DType dt, float scale) {
  HostTensor h(s, dt);
  uint32_t state = 12345;
  for (int64_t i = 0; i < h.numel(); ++i) {
    float v = lcg_value(state, scale);
    if (dt == DType::f32) h.as<float>()[i] = v;
    else if (dt == DType::bf16) h.as<uint16_t>()[i] = f32_to_bf16(v);
    else h.as<uint16_t>()[i] = f32_to_f16(v);
  }
  return Tensor::upload(ctx, h);
}

std::string dims(int64_t cin, int64_t cout, int64_t f, int64_t h, int64_t w) {
  return std::to_string(cin) + "->" + std::to_string(cout) + " " + std::to_string(f) + "x" + std::to_string(h) + "x" +
         std::to_string(w);
}

std::string fixed(double v, int digits = 2) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// One convolution as the CPU does it best: im2col (Cin*kt*kh*kw rows, one column per output pixel) then
// OpenBLAS sgemm; GFLOP/s of the two together over `frames_out` output frames (few: the im2col buffer of
// a whole clip would not fit in memory).
struct CpuConv {
  int64_t cin, cout, kt, kh, kw, stride, h, w, pad_t, pad_l, frames_out;
  bool upsample = false;  // nearest x2 before the conv (H, W: input sizes)
};

double cpu_im2col_sgemm_gflops(const CpuConv& c) {
#ifdef DVS_HAVE_BLAS
  if (c.cout == 0) return 0;  // not asked for (the family rows)
  int64_t up = c.upsample ? 2 : 1, hu = up * c.h, wu = up * c.w;
  int64_t ho = (hu + 2 * c.pad_t - c.kh) / c.stride + 1, wo = (wu + 2 * c.pad_l - c.kw) / c.stride + 1;
  int64_t frames_in = c.frames_out + c.kt - 1;
  std::vector<float> x(size_t(c.cin * frames_in * c.h * c.w)), wt(size_t(c.cout * c.cin * c.kt * c.kh * c.kw));
  uint32_t state = 7;
  for (float& v : x) v = lcg_value(state, 1.f);
  for (float& v : wt) v = lcg_value(state, 0.05f);
  const int64_t m = c.frames_out * ho * wo, k = c.cin * c.kt * c.kh * c.kw;
  std::vector<float> col(size_t(m * k)), y(size_t(m * c.cout));
  auto run = [&] {
    // col row r = (ci, a, u, v), column = output pixel; zero where the tap is padding.
    for (int64_t ci = 0; ci < c.cin; ++ci)
      for (int64_t a = 0; a < c.kt; ++a)
        for (int64_t u = 0; u < c.kh; ++u)
          for (int64_t v = 0; v < c.kw; ++v) {
            float* row = col.data() + size_t((((ci * c.kt + a) * c.kh + u) * c.kw + v) * m);
            for (int64_t f = 0; f < c.frames_out; ++f)
              for (int64_t i = 0; i < ho; ++i) {
                int64_t ih = i * c.stride - c.pad_t + u;
                float* out = row + (f * ho + i) * wo;
                if (ih < 0 || ih >= hu) {
                  std::fill(out, out + wo, 0.f);
                  continue;
                }
                const float* src = x.data() + size_t(((ci * frames_in + f + a) * c.h + ih / up) * c.w);
                for (int64_t j = 0; j < wo; ++j) {
                  int64_t iw = j * c.stride - c.pad_l + v;
                  out[j] = iw < 0 || iw >= wu ? 0.f : src[iw / up];
                }
              }
          }
    // y [Cout][M] = w [Cout][K] * col [K][M], in BLAS's column-major terms y^T = col^T * w^T.
    const int M = int(m), N = int(c.cout), K = int(k);
    const float one = 1, zero = 0;
    sgemm_("N", "N", &M, &N, &K, &one, col.data(), &M, wt.data(), &K, &zero, y.data(), &M);
  };
  double ms = Bench::time_ms(run, 0.3);
  return 2.0 * double(m) * double(k) * double(c.cout) / (ms * 1e6);
#else
  (void)c;
  return 0;
#endif
}

// DVS_BENCH_CONV_LOOP=SECONDS (a profiling aid): submits the first convolution measured over and over for that
// long, so that a sampling profiler (perf record -p PID) sees nothing else, then ends the program.
[[noreturn]] void profile_loop(vk::Recorder& rec, const std::string& op, const std::string& shape, const char* value) {
  char* end = nullptr;
  const double seconds = std::strtod(value, &end);
  if (end == value || *end != '\0' || !(seconds > 0)) {
    std::cerr << "DVS_BENCH_CONV_LOOP must be a number of seconds above 0, got '" << value << "'\n";
    std::exit(2);
  }
  std::cout << "DVS_BENCH_CONV_LOOP: submitting " << op << " " << shape << " for " << seconds << " s (pid " << getpid()
            << ")" << std::endl;
  const auto t0 = std::chrono::steady_clock::now();
  int64_t submits = 0;
  while (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < seconds) rec.submit(), ++submits;
  std::cout << submits << " submissions" << std::endl;
  std::exit(0);
}

// Times one recorded convolution and reports it with: its ratio to the FMA peak measured just before (wall
// clock) and per CPU-second, and the CPU's im2col + sgemm rate for the same convolution.
// Set by the family rows (conv_families_group): appended to the op's name; no CPU im2col baseline then.
std::string g_family_suffix;

void measure(Bench& b, FmaPeakRun& peak, const std::string& op_name, const std::string& shape, double flops,
             const std::function<void(vk::Recorder&)>& record, CpuConv cpu, const std::string& note) {
  const std::string op = op_name + g_family_suffix;
  if (!g_family_suffix.empty()) cpu.cout = 0;
  vk::Recorder rec(b.ctx());
  rec.begin();
  record(rec);
  rec.end();
  if (const char* loop = std::getenv("DVS_BENCH_CONV_LOOP")) profile_loop(rec, op, shape, loop);
  double peak_ms = Bench::time_ms([&] { peak.recorder.submit(); }, 0.3);
  double peak_now = peak.flops / (peak_ms * 1e6);
  double ms = Bench::time_ms([&] { rec.submit(); }, 0.3);
  double gflops = flops / (ms * 1e6);
  std::string n = "peak now " + fixed(peak_now, 1) + " GFLOP/s: " + fixed(gflops / peak_now) + "x";
  if (b.ctx().caps().type == VK_PHYSICAL_DEVICE_TYPE_CPU) {
    double per_cpu = gflop_per_cpu_second([&] { rec.submit(); }, flops);
    double peak_cpu = gflop_per_cpu_second([&] { peak.recorder.submit(); }, peak.flops);
    n += "; per CPU-second " + fixed(per_cpu / peak_cpu) + "x";
  }
  double cpu_gflops = cpu_im2col_sgemm_gflops(cpu);
  if (cpu_gflops > 0) n += "; im2col+sgemm " + fixed(cpu_gflops, 1) + " GFLOP/s (dvs " + fixed(gflops / cpu_gflops) + "x)";
  if (!note.empty()) n += "; " + note;
  b.report({op, shape, ms, gflops, 0, n});
}

void conv3d(Bench& b, FmaPeakRun& peak, int64_t cin, int64_t cout, int64_t f, int64_t h, int64_t w, DType wdt, bool cached) {
  vk::Context& ctx = b.ctx();
  Tensor x = filled(ctx, {1, cin, f, h, w}, DType::f32, 1.f);
  Tensor wt = filled(ctx, {cout, cin, 3, 3, 3}, wdt, 0.05f);
  Tensor bias = filled(ctx, {cout}, wdt, 0.1f);
  Tensor y = Tensor::empty(ctx, {1, cout, f, h, w}, DType::f32);
  Tensor cache = filled(ctx, {1, cin, 2, h, w}, DType::f32, 1.f);
  double flops = 2.0 * double(cout) * double(cin) * 27.0 * double(f * h * w);
  measure(b, peak, std::string("causal_conv3d_3x3x3_") + dtype_name(wdt), dims(cin, cout, f, h, w), flops,
          [&](vk::Recorder& rec) {
            ops::causal_conv3d(rec, x, wt, &bias, y, cached ? &cache : nullptr, cached ? &cache : nullptr);
          },
          {cin, cout, 3, 3, 3, 1, h, w, 1, 1, 1}, cached ? "with cache in/out" : "");
}

void conv2d(Bench& b, FmaPeakRun& peak, const char* name, int64_t cin, int64_t cout, int64_t f, int64_t h, int64_t w,
            int64_t k, const ops::Conv2dParams& p, DType wdt) {
  vk::Context& ctx = b.ctx();
  Tensor x = filled(ctx, {1, cin, f, h, w}, DType::f32, 1.f);
  Tensor wt = filled(ctx, {cout, cin, k, k}, wdt, 0.05f);
  Tensor bias = filled(ctx, {cout}, wdt, 0.1f);
  Shape ys = ops::conv2d_shape(x.shape(), wt.shape(), p);
  Tensor y = Tensor::empty(ctx, ys, DType::f32);
  double outputs = double(shape_numel(ys)) / double(cout);
  double flops = 2.0 * double(cout) * double(cin * k * k) * outputs;
  measure(b, peak, std::string(name) + "_" + dtype_name(wdt), dims(cin, cout, f, h, w), flops,
          [&](vk::Recorder& rec) { ops::conv2d(rec, x, wt, &bias, y, p); },
          {cin, cout, 1, k, k, p.stride, h, w, p.pad_top, p.pad_left, 1}, "");
}

void conv1x1(Bench& b, FmaPeakRun& peak, int64_t cin, int64_t cout, int64_t f, int64_t h, int64_t w) {
  vk::Context& ctx = b.ctx();
  Tensor x = filled(ctx, {1, cin, f, h, w}, DType::f32, 1.f);
  Tensor wt = filled(ctx, {cout, cin, 1, 1, 1}, DType::bf16, 0.05f);
  Tensor y = Tensor::empty(ctx, {1, cout, f, h, w}, DType::f32);
  double flops = 2.0 * double(cout) * double(cin) * double(f * h * w);
  measure(b, peak, "conv1x1_bf16", dims(cin, cout, f, h, w), flops,
          [&](vk::Recorder& rec) { ops::conv1x1(rec, x, wt, nullptr, y); }, {cin, cout, 1, 1, 1, 1, h, w, 0, 0, f}, "");
}

// CogVideoXUpsample3D (compress_time): nearest x2 + conv 3x3, fused.
void upsample_conv(Bench& b, FmaPeakRun& peak, int64_t c, int64_t f, int64_t h, int64_t w) {
  vk::Context& ctx = b.ctx();
  Tensor x = filled(ctx, {1, c, f, h, w}, DType::f32, 1.f);
  Tensor wt = filled(ctx, {c, c, 3, 3}, DType::bf16, 0.05f);
  Tensor bias = filled(ctx, {c}, DType::bf16, 0.1f);
  Shape us = ops::upsample2x_shape(x.shape(), true);
  Tensor y = Tensor::empty(ctx, {us[0], c, us[2], us[3], us[4]}, DType::f32);
  double flops = 2.0 * double(c) * double(c * 9) * double(us[2] * us[3] * us[4]);
  measure(b, peak, "upsample2x_conv3x3_bf16", dims(c, c, f, h, w) + " ->" + std::to_string(us[2]) + "x" +
          std::to_string(us[3]) + "x" + std::to_string(us[4]), flops,
          [&](vk::Recorder& rec) { ops::upsample2x_conv3x3(rec, x, wt, &bias, y, true); },
          {c, c, 1, 3, 3, 1, h, w, 1, 1, 1, true}, "CogVideoXUpsample3D");
}

Result time_resampling(const std::string& op, const std::string& shape, double bytes, vk::Recorder& rec, const char* note) {
  double ms = Bench::time_ms([&] { rec.submit(); });
  return {op, shape, ms, 0, bytes / (ms * 1e6), note};
}

void resampling(Bench& b, int64_t c, int64_t f, int64_t h, int64_t w) {
  vk::Context& ctx = b.ctx();
  std::string d = std::to_string(c) + "x" + std::to_string(f) + "x" + std::to_string(h) + "x" + std::to_string(w);
  {
    Tensor x = filled(ctx, {1, c, f, h, w}, DType::f32, 1.f);
    Tensor y = Tensor::empty(ctx, {1, c, ops::downsample_time_frames(f), h, w}, DType::f32);
    vk::Recorder rec(ctx);
    rec.begin();
    ops::avgpool_time_pairs(rec, x, y);
    rec.end();
    b.report(time_resampling("avgpool_time_pairs", d, double(x.bytes() + y.bytes()), rec, ""));
  }
  {
    int64_t fl = (f - 1) / 4 + 1;  // a latent-like frame count (odd)
    Tensor x = filled(ctx, {1, c, fl, h / 2, w / 2}, DType::f32, 1.f);
    Tensor y = Tensor::empty(ctx, ops::upsample2x_shape(x.shape(), true), DType::f32);
    vk::Recorder rec(ctx);
    rec.begin();
    ops::upsample2x(rec, x, y, true);
    rec.end();
    b.report(time_resampling("upsample2x_time", std::to_string(c) + "x" + std::to_string(fl) + "x" + std::to_string(h / 2) +
                                                    "x" + std::to_string(w / 2),
                             double(x.bytes() + y.bytes()), rec, "compress_time"));
  }
}

// The VAE's convolution shapes (channel widths 128/256/256/512 as in CogVideoX-5B), at a spatial size
// that keeps each measurement around a second on two CPU threads.
// --quick: the first three shapes only. DVS_BENCH_CONV_TILE=rows,cols[,lanes[,k_unroll]] overrides the register
// block of tensor/kernel_tuning.cpp (to try a tile before it goes into the table).
void conv_group(Bench& b) {
  bool q = b.quick();
  if (const char* env = std::getenv("DVS_BENCH_CONV_TILE")) {
    ops::ConvRegisterBlock blk;
    if (std::sscanf(env, "%d,%d,%d,%d", &blk.rows, &blk.cols, &blk.lanes, &blk.k_unroll) < 2) {
      std::cerr << "DVS_BENCH_CONV_TILE must be rows,cols[,lanes[,k_unroll]], got '" << env << "'\n";
      return;
    }
    ops::set_conv_register_block(blk);
    std::cout << "conv register block from DVS_BENCH_CONV_TILE: " << env << "\n";
  }
  FmaPeakRun peak(b.ctx());
  // Encoder down block 0 / decoder up block 3 (128 channels, full resolution; 1/8 of 480x720 here).
  conv3d(b, peak, 128, 128, q ? 3 : 9, 60, 90, DType::bf16, false);
  conv3d(b, peak, 128, 128, 3, 60, 90, DType::f32, true);
  conv3d(b, peak, 256, 256, 3, 30, 45, DType::bf16, false);
  if (q) return;
  conv3d(b, peak, 128, 256, 3, 30, 45, DType::bf16, false);  // down block 1's first conv
  conv3d(b, peak, 256, 512, 3, 16, 24, DType::bf16, false);  // down block 3's first conv
  conv3d(b, peak, 512, 512, 3, 16, 24, DType::bf16, false);  // mid block, decoder up block 0
  conv3d(b, peak, 512, 256, 3, 30, 45, DType::bf16, false);  // decoder up block 2's first conv
  conv3d(b, peak, 16, 512, 3, 16, 24, DType::bf16, false);   // decoder conv_in (latent channels)
  conv3d(b, peak, 3, 128, 3, 60, 90, DType::bf16, false);    // encoder conv_in: 3 input channels
  conv3d(b, peak, 128, 3, 3, 60, 90, DType::bf16, false);    // decoder conv_out: 3 output channels
  conv2d(b, peak, "conv2d_3x3_s2_down", 128, 128, 1, 120, 180, 3, ops::Conv2dParams::downsample3x3(), DType::bf16);
  conv2d(b, peak, "conv2d_3x3_s2_down", 256, 256, 1, 60, 90, 3, ops::Conv2dParams::downsample3x3(), DType::bf16);
  conv2d(b, peak, "conv2d_3x3", 128, 128, 1, 60, 90, 3, ops::Conv2dParams::same3x3(), DType::bf16);
  conv2d(b, peak, "conv2d_patch_2x2", 32, 3072, 1, 60, 90, 2, ops::Conv2dParams::patch(true), DType::bf16);
  conv1x1(b, peak, 128, 256, 3, 60, 90);
  conv1x1(b, peak, 512, 256, 3, 30, 45);
  upsample_conv(b, peak, 512, 3, 16, 24);
  upsample_conv(b, peak, 256, 3, 30, 45);
  resampling(b, 128, 9, 120, 180);
}

Registration reg("conv", 10, conv_group);

// The GPU kernel families of the convolutions (kernel_tuning.hpp) forced in turn at the VAE's shapes:
// "tiled" (shared-memory tiles, fp32) on any device, "coopmat" (tensor cores, fp16 operands) where the
// device has them. Rows are named op[family]; the default family's rows are group "conv".
void conv_families_group(Bench& b) {
  const bool q = b.quick();
  std::vector<std::string> families = {"tiled"};
  if (ops::device_tuning(b.ctx().caps()).coopmat.defined()) families.push_back("coopmat");
  FmaPeakRun peak(b.ctx());
  for (const std::string& fam : families) {
    ops::ScopedTuningOverride scope("conv=" + fam);
    g_family_suffix = "[" + fam + "]";
    conv3d(b, peak, 128, 128, 3, 60, 90, DType::bf16, false);
    conv3d(b, peak, 256, 256, 3, 30, 45, DType::bf16, false);
    if (!q) {
      conv3d(b, peak, 512, 512, 3, 16, 24, DType::bf16, false);
      conv3d(b, peak, 128, 128, 3, 60, 90, DType::f32, true);
      conv3d(b, peak, 3, 128, 3, 60, 90, DType::bf16, false);
      conv3d(b, peak, 128, 3, 3, 60, 90, DType::bf16, false);
      conv2d(b, peak, "conv2d_3x3_s2_down", 128, 128, 1, 120, 180, 3, ops::Conv2dParams::downsample3x3(), DType::bf16);
      conv2d(b, peak, "conv2d_patch_2x2", 32, 3072, 1, 60, 90, 2, ops::Conv2dParams::patch(true), DType::bf16);
      conv1x1(b, peak, 128, 256, 3, 60, 90);
      upsample_conv(b, peak, 256, 3, 30, 45);
    }
    g_family_suffix.clear();
  }
}

Registration reg_families("conv_families", 12, conv_families_group);

// A whole VAE encode of a 9-frame clip and the decode of its latent, with a random-weight VAE of the real
// channel widths (written once to a temporary folder; DVS_BENCH_VAE_DIR=folder/vae uses another VAE).
// One untimed call first (pipeline compilation), then one timed call each.
void vae_group(Bench& b) {
  vk::Context& ctx = b.ctx();
  std::filesystem::path dir;
  bool own = false;
  if (const char* env = std::getenv("DVS_BENCH_VAE_DIR")) {
    dir = env;
  } else {
    std::filesystem::path root = std::filesystem::temp_directory_path() / ("dvs-bench-vae-" + std::to_string(getpid()));
    models::TinyModelSpec spec;
    spec.vae_channels = {128, 256, 256, 512};
    spec.vae_groups = 32;
    spec.latent_channels = 16;
    models::write_tiny_model(root, spec);
    dir = root / "vae";
    own = true;
  }
  const int64_t frames = 9, h = b.quick() ? 32 : 64, w = b.quick() ? 48 : 96;
  {
    models::CogVideoXVae vae(ctx, dir);
    const auto& cfg = vae.config();
    std::string widths;
    for (int64_t c : cfg.block_out_channels) widths += (widths.empty() ? "" : "/") + std::to_string(c);
    std::string what = "widths " + widths + ", " + std::to_string(cfg.layers_per_block) + " layers per block";
    Tensor video = filled(ctx, {1, cfg.in_channels, frames, h, w}, DType::f32, 0.9f);
    std::string shape = std::to_string(frames) + "x" + std::to_string(h) + "x" + std::to_string(w);
    auto timed = [&](const std::function<void()>& fn) {
      fn();  // pipeline compilation, first touch
      auto t0 = std::chrono::steady_clock::now();
      double c0 = cpu_seconds();
      fn();
      double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      return std::pair<double, double>{wall, cpu_seconds() - c0};
    };
    models::VaePosterior post;
    auto [enc_s, enc_cpu] = timed([&] { post = vae.encode(video); });
    b.report({"vae_encode", shape, enc_s * 1e3, 0, 0,
              fixed(enc_s / double(frames), 3) + " s per frame (" + fixed(enc_cpu, 1) + " CPU-s); " + what});
    Tensor z = post.mean;
    Tensor out;
    auto [dec_s, dec_cpu] = timed([&] { out = vae.decode(z); });
    b.report({"vae_decode", shape, dec_s * 1e3, 0, 0,
              fixed(dec_s / double(frames), 3) + " s per frame (" + fixed(dec_cpu, 1) + " CPU-s); " + what});
  }
  if (own) std::filesystem::remove_all(dir.parent_path());
}

Registration reg_vae("conv_vae", 11, vae_group);

}  // namespace
}  // namespace dvs::bench
