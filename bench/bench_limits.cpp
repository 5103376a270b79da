// The machine's own limits, measured first so every other figure is printed as a ratio to them.
#include <algorithm>
#include <cstring>
#include <string>
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
  FmaPeakRun run(b.ctx());
  double ms = Bench::time_ms([&] { run.recorder.submit(); });
  b.limits().fma_peak_gflops = run.flops / (ms * 1e6);
  const std::string shape = "32768 invocations, " + std::to_string(run.chains) + " chains x " + std::to_string(run.unroll);
  b.report({"fma_peak_f32", shape, ms, run.flops / (ms * 1e6), 0, "device limit (the fastest shape tried)"});
  if (b.ctx().caps().type == VK_PHYSICAL_DEVICE_TYPE_CPU) {
    b.limits().fma_peak_per_cpu_second = gflop_per_cpu_second([&] { run.recorder.submit(); }, run.flops);
    char note[128];
    std::snprintf(note, sizeof note, "%.1f GFLOP per CPU-second: the reference for the per-CPU-second ratios",
                  b.limits().fma_peak_per_cpu_second);
    b.report({"fma_peak_per_cpu_second", shape, 0, 0, 0, note});
  }
}

void copy_bandwidth(Bench& b) {
  CopyRun copy(b.ctx());
  double ms = Bench::time_ms([&] { copy.recorder.submit(); });
  b.limits().copy_gbps = copy.bytes / (ms * 1e6);
  b.report({"copy_shader", "64MiB", ms, 0, b.limits().copy_gbps, "device limit (read+write bytes)"});
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
