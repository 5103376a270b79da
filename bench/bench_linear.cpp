// Linear / GEMM throughput: fp32, bf16 and f16 weights on square, model-class and GEMV shapes, with the
// epilogue cost on one shape. FLOPs = 2·M·N·K. DVS_LINEAR_KERNEL=rows,cols,sg_m pins a kernel variant
// (for tuning).
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include "harness.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_linear.hpp"
#include "tensor/tensor.hpp"
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

void run_case(Bench& b, const Case& c, DType wdt, bool epilogue) {
  vk::Context& ctx = b.ctx();
  Tensor x = Tensor::upload(ctx, random_host({c.m, c.k}, DType::f32, 1), "bench x");
  Tensor w = Tensor::upload(ctx, random_host({c.n, c.k}, wdt, 2), "bench w");
  Tensor y = Tensor::empty(ctx, {c.m, c.n}, DType::f32, "bench y");
  ops::LinearEpilogue ep;
  if (epilogue) {
    ep.bias = Tensor::upload(ctx, random_host({c.n}, wdt, 3));
    ep.activation = ops::Activation::gelu_tanh;
    ep.gate = Tensor::upload(ctx, random_host({c.n}, DType::f32, 4));
    ep.residual = Tensor::upload(ctx, random_host({c.m, c.n}, DType::f32, 5));
  }
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
  vk::Recorder rec(ctx);
  rec.begin();
  ops::linear_batched_with(rec, x, w, y, s, ep, kern);
  rec.end();
  double ms = Bench::time_ms([&] { rec.submit(); }, b.quick() ? 0.2 : 1.0);
  double gflops = 2.0 * double(c.m) * double(c.n) * double(c.k) / (ms * 1e6);
  std::string op = std::string("linear_") + dtype_name(wdt) + (epilogue ? "_bias_gelu_gated_res" : "");
  char shape[64], note[96];
  std::snprintf(shape, sizeof shape, "%lldx%lldx%lld", (long long)c.m, (long long)c.n, (long long)c.k);
  std::snprintf(note, sizeof note, "%s, tile %dx%d x%s", c.name, kern.rows, kern.cols,
                kern.vectorized ? "vec8" : "scalar");
  b.report({op, shape, ms, gflops, 0, note});
}

void linear(Bench& b) {
  const Case cases[] = {
      {"square", 1024, 1024, 1024, true},
      {"CogVideoX attn proj class", 2048, 3072, 3072, false},
      {"GEMV (M=1)", 1, 3072, 3072, true},
      {"T5 FFN (M=226)", 226, 10240, 4096, false},
      {"CogVideoX FFN class", 4096, 12288, 3072, false},
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
}

Registration reg("linear", 10, linear);

}  // namespace
}  // namespace dvs::bench
