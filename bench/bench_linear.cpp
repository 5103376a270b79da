// Linear / GEMM throughput: fp32, bf16 and f16 weights on square, model-class and GEMV shapes, with the
// epilogue cost on one shape. FLOPs = 2·M·N·K. DVS_LINEAR_KERNEL=rows,cols,sg_m pins a texel kernel
// variant (for tuning). The main rows run the family the device's tuning picks (DVS_TUNING=linear=... moves
// them); rows named linear_tiled_* / linear_coopmat_* then force the tiled family (every device) and the
// coopmat family (devices with a cooperative-matrix shape) on a few shapes.

#include <chrono>
#include <cstdio>
#include <algorithm>
#include <cstdlib>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "harness.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_linear.hpp"
#include "tensor/tensor.hpp"
#include "vk/pipeline.hpp"
#include "vk/recorder.hpp"

namespace dvs::bench {
namespace {

HostTensor random_host(Shape s, DType dt, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<float> v(size_t(shape_numel(s)));
  for (float& f : v) f = u(rng);
  HostTensor h = HostTensor::from_f32(s, v);
  if (dt == DType::f32) return h;
  HostTensor o(s, dt);
  for (size_t i = 0; i < v.size(); ++i)
    o.as<uint16_t>()[i] = dt == DType::bf16 ? f32_to_bf16(v[i]) : f32_to_f16(v[i]);
  return o;
}

struct Case {
  const char* name;
  int64_t m, n, k;
  bool quick;  // also in --quick runs
};

void run_case(Bench& b, const Case& c, DType wdt, bool epilogue, const char* family_row = "") {
  vk::Context& ctx = b.ctx();
  Tensor x = Tensor::upload(ctx, random_host({c.m, c.k}, DType::f32, 1), "bench x");
  ops::LinearEpilogue ep;
  if (epilogue) {
    ep.bias = Tensor::upload(ctx, random_host({c.n}, wdt, 3));
    ep.activation = ops::Activation::gelu_tanh;
    ep.gate = Tensor::upload(ctx, random_host({c.n}, DType::f32, 4));
    ep.residual = Tensor::upload(ctx, random_host({c.m, c.n}, DType::f32, 5));
  }
  // A weight larger than one binding (f32 FFN weights on lavapipe: 144 MiB > 128 MiB) is split over N by
  // linear itself (weight row chunks, Y column slices), as in the models.
  Tensor w = Tensor::upload(ctx, random_host({c.n, c.k}, wdt, 2), "bench w");
  Tensor y = Tensor::empty(ctx, {c.m, c.n}, DType::f32, "bench y");
  uint32_t calls = 1;  // dispatches of the last recording (more than 1: linear split the weight)
  auto record = [&](vk::Recorder& r, const ops::LinearShape& sh, const ops::LinearKernel& kern) {
    const uint32_t before = r.dispatch_count();
    ops::linear_batched_with(r, x, w, y, sh, ep, kern);
    calls = r.dispatch_count() - before;
  };
  ops::LinearShape s;
  s.m = c.m;
  s.n = c.n;
  s.k = c.k;
  ops::LinearKernel kern = ops::choose_linear_kernel(ctx, s, wdt);
  if (const char* env = std::getenv("DVS_LINEAR_KERNEL")) {
    int r = 0, co = 0, sg = 0;
    if (std::sscanf(env, "%d,%d,%d", &r, &co, &sg) == 3 && kern.rows >= 8) {
      kern.rows = r;
      kern.cols = co;
      kern.sg_m = sg;
    }
  }
  const double flops = 2.0 * double(c.m) * double(c.n) * double(c.k);
  double ms = 0, per_cpu = 0;
  if (flops < 5e10) {
    vk::Recorder rec(ctx);
    rec.begin();
    record(rec, s, kern);
    rec.end();
    ms = Bench::time_ms([&] { rec.submit(); }, b.quick() ? 0.2 : 1.0);
    per_cpu = gflop_per_cpu_second([&] { rec.submit(); }, flops);
  } else {
    // Large shapes: compile the same pipeline on a few rows, then time single calls.
    ops::LinearShape small = s;
    small.m = std::min<int64_t>(s.m, 64);
    ops::run_now(ctx, [&](vk::Recorder& r) { record(r, small, kern); });
    vk::Recorder rec(ctx);
    rec.begin();
    record(rec, s, kern);
    rec.end();
    double c0 = cpu_seconds();
    auto t0 = std::chrono::steady_clock::now();
    rec.submit();
    ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    per_cpu = flops / ((cpu_seconds() - c0) * 1e9);
  }
  double gflops = flops / (ms * 1e6);
  std::string op = std::string("linear_") + family_row + dtype_name(wdt) + (epilogue ? "_bias_gelu_gated_res" : "");
  char shape[64], note[200], wrate[64] = "";
  if (c.m == 1)  // GEMV is bound by streaming the weight
    std::snprintf(wrate, sizeof wrate, ", weight read %.2f GB/s", double(w.bytes()) / (ms * 1e6));
  if (calls > 1) std::snprintf(wrate, sizeof wrate, ", split in %u dispatches", calls);
  std::snprintf(shape, sizeof shape, "%lldx%lldx%lld", (long long)c.m, (long long)c.n, (long long)c.k);
  char tile[64];
  if (kern.family == ops::KernelFamily::texel)
    std::snprintf(tile, sizeof tile, "tile %dx%d lanes %d %s", kern.rows, kern.cols, kern.lanes,
                  kern.vectorized ? "vec8" : "scalar");
  else
    std::snprintf(tile, sizeof tile, "%s %dx%dx%d", ops::kernel_family_name(kern.family), kern.tile_m, kern.tile_n,
                  kern.tile_k);
  std::snprintf(note, sizeof note, "%s%s, %s; %.1f GFLOP per CPU-second = %.2fx fma_peak per CPU-second", c.name, wrate,
                tile, per_cpu, b.limits().fma_peak_per_cpu_second > 0 ? per_cpu / b.limits().fma_peak_per_cpu_second : 0.0);
  b.report({op, shape, ms, gflops, 0, note});
}

// DVS_LINEAR_TUNE="rows,cols,sg_m;..." times each listed variant on DVS_LINEAR_CASE (default 1024³), f32 and
// bf16 weights, twice in turn so that load changes from other processes show up as spread.
void tune(Bench& b, const char* list) {
  const char* only = std::getenv("DVS_LINEAR_CASE");
  int64_t m = 1024, n = 1024, k = 1024;
  if (only) std::sscanf(only, "%lldx%lldx%lld", (long long*)&m, (long long*)&n, (long long*)&k);
  std::vector<ops::LinearKernel> ks;
  std::string l = list;
  for (size_t pos = 0; pos < l.size();) {
    size_t e = l.find(';', pos);
    if (e == std::string::npos) e = l.size();
    ops::LinearKernel kern;
    if (std::sscanf(l.substr(pos, e - pos).c_str(), "%d,%d,%d", &kern.rows, &kern.cols, &kern.sg_m) == 3) ks.push_back(kern);
    pos = e + 1;
  }
  vk::Context& ctx = b.ctx();
  const double peak_per_cpu = b.limits().fma_peak_per_cpu_second;
  for (DType wdt : {DType::f32, DType::bf16}) {
    Tensor x = Tensor::upload(ctx, random_host({m, k}, DType::f32, 1));
    Tensor w = Tensor::upload(ctx, random_host({n, k}, wdt, 2));
    Tensor y = Tensor::empty(ctx, {m, n}, DType::f32);
    ops::LinearShape s;
    s.m = m;
    s.n = n;
    s.k = k;
    const int rounds = std::getenv("DVS_LINEAR_ROUNDS") ? std::atoi(std::getenv("DVS_LINEAR_ROUNDS")) : 2;
    for (int round = 0; round < rounds; ++round)
      for (const ops::LinearKernel& kern : ks) {
        vk::Recorder rec(ctx);
        rec.begin();
        ops::linear_batched_with(rec, x, w, y, s, {}, kern);
        rec.end();
        rec.submit();  // compile, first touch
        double c0 = cpu_seconds();
        auto t0 = std::chrono::steady_clock::now();
        const int reps = 2;
        for (int i = 0; i < reps; ++i) rec.submit();
        double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / reps;
        double per_cpu = 2.0 * m * n * k * reps / ((cpu_seconds() - c0) * 1e9);
        char shape[64], note[96];
        std::snprintf(shape, sizeof shape, "%lldx%lldx%lld", (long long)m, (long long)n, (long long)k);
        std::snprintf(note, sizeof note, "rows %d cols %d sg_m %d: %.2f GFLOP/cpu-s = %.3f of peak/cpu-s", kern.rows,
                      kern.cols, kern.sg_m, per_cpu, per_cpu / peak_per_cpu);
        b.report({std::string("tune_") + dtype_name(wdt), shape, ms, 2.0 * m * n * k / (ms * 1e6), 0, note});
      }
  }
}

void linear(Bench& b) {
  if (const char* list = std::getenv("DVS_LINEAR_TUNE")) return tune(b, list);
  const Case cases[] = {
      {"square", 1024, 1024, 1024, true},
      {"CogVideoX attn proj class", 2048, 3072, 3072, false},
      {"GEMV (M=1)", 1, 3072, 3072, true},
      {"T5 FFN (M=226)", 226, 10240, 4096, false},
      {"CogVideoX FFN up-proj, 2048-row chunk", 2048, 12288, 3072, false},
      {"CogVideoX FFN down-proj, 2048-row chunk", 2048, 3072, 12288, false},
  };
  const char* only = std::getenv("DVS_LINEAR_CASE");  // substring of the shape, for tuning runs
  for (DType wdt : {DType::f32, DType::bf16, DType::f16}) {
    for (const Case& c : cases) {
      if (b.quick() && !c.quick) continue;
      if (wdt == DType::f16 && c.m * c.n * c.k > (int64_t(1) << 33)) continue;  // f16: skip the largest
      char shape[64];
      std::snprintf(shape, sizeof shape, "%lldx%lldx%lld", (long long)c.m, (long long)c.n, (long long)c.k);
      if (only && std::string(shape).find(only) == std::string::npos) continue;
      run_case(b, c, wdt, false);
    }
  }
  if (!only || std::string("1024x1024x1024").find(only) != std::string::npos)
    run_case(b, cases[0], DType::bf16, true);

  // The storage-buffer families, forced, where the device has them (rows beside the device's own family).
  const Case family_cases[] = {cases[0], cases[2], cases[1]};
  const bool has_coopmat = ops::device_tuning(b.ctx().caps()).coopmat.defined();
  for (const char* family : {"tiled", "coopmat"}) {
    if (std::string(family) == "coopmat" && !has_coopmat) continue;
    ops::ScopedTuningOverride force(std::string("linear=") + family);
    for (const Case& c : family_cases) {
      if (b.quick() && !c.quick) continue;
      char shape[64];
      std::snprintf(shape, sizeof shape, "%lldx%lldx%lld", (long long)c.m, (long long)c.n, (long long)c.k);
      if (only && std::string(shape).find(only) == std::string::npos) continue;
      for (DType wdt : {DType::f32, DType::bf16}) run_case(b, c, wdt, false, (std::string(family) + "_").c_str());
    }
  }
}

Registration reg("linear", 10, linear);

}  // namespace
}  // namespace dvs::bench
