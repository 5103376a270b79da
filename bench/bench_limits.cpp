// The machine's own limits, measured first so every other figure is printed as a ratio to them.
#include <algorithm>
#include <cstring>
#include <vector>

#include "harness.hpp"
#include "vk/pipeline.hpp"
#include "vk/recorder.hpp"
#include "vk/transfer.hpp"

#ifdef DVS_HAVE_BLAS
extern "C" void sgemm_(const char* ta, const char* tb, const int* m, const int* n, const int* k, const float* alpha,
                       const float* a, const int* lda, const float* b, const int* ldb, const float* beta, float* c,
                       const int* ldc);
#endif

namespace dvs::bench {
namespace {

void fma_peak(Bench& b) {
  vk::Context& ctx = b.ctx();
  const uint32_t iters = 1024, groups = 512, invocations = groups * 64;
  vk::Buffer out = ctx.allocator().allocate(invocations * 4);
  uint32_t spec[] = {iters};
  const vk::Pipeline& p = ctx.pipelines().get("bench/fma_peak", spec);
  vk::Recorder rec(ctx);
  rec.begin();
  float push[2] = {0.999f, 1e-3f};
  rec.dispatch(p, {out.view()}, push, sizeof push, groups);
  rec.end();
  double ms = Bench::time_ms([&] { rec.submit(); });
  double flops = double(invocations) * 64 * iters * 2;  // 16 vec4 FMAs per round
  b.limits().fma_peak_gflops = flops / (ms * 1e6);
  b.report({"fma_peak_f32", std::to_string(invocations) + "x64x" + std::to_string(iters), ms, flops / (ms * 1e6), 0,
            "device limit"});
}

void copy_bandwidth(Bench& b) {
  vk::Context& ctx = b.ctx();
  const uint64_t bytes = 64ull << 20;
  vk::Buffer src = ctx.allocator().allocate(bytes), dst = ctx.allocator().allocate(bytes);
  ctx.transfer().fill_zero(src.view());
  const vk::Pipeline& p = ctx.pipelines().get("bench/copy");
  vk::Recorder rec(ctx);
  rec.begin();
  uint32_t n4 = uint32_t(bytes / 16);
  rec.dispatch(p, {src.view(), dst.view()}, &n4, 4, std::min(4096u, (n4 + 63) / 64));
  rec.end();
  double ms = Bench::time_ms([&] { rec.submit(); });
  double gbps = 2.0 * double(bytes) / (ms * 1e6);
  b.limits().copy_gbps = gbps;
  b.report({"copy_shader", "64MiB", ms, 0, gbps, "device limit (read+write bytes)"});
}

void openblas_sgemm(Bench& b) {
#ifdef DVS_HAVE_BLAS
  const int n = b.quick() ? 512 : 1024;
  std::vector<float> A(size_t(n) * n, 0.5f), B(size_t(n) * n, 0.25f), C(size_t(n) * n);
  float one = 1, zero = 0;
  double ms = Bench::time_ms([&] { sgemm_("N", "N", &n, &n, &n, &one, A.data(), &n, B.data(), &n, &zero, C.data(), &n); });
  double gflops = 2.0 * n * double(n) * n / (ms * 1e6);
  b.limits().sgemm_gflops = gflops;
  std::string s = std::to_string(n);
  b.report({"openblas_sgemm", s + "x" + s + "x" + s, ms, gflops, 0, "host limit, OPENBLAS_NUM_THREADS"});
#else
  std::cout << "openblas_sgemm: not built (libopenblas-dev missing)\n";
#endif
}

void limits(Bench& b) {
  fma_peak(b);
  copy_bandwidth(b);
  openblas_sgemm(b);
}

Registration reg("limits", 0, limits);

}  // namespace
}  // namespace dvs::bench
