#include "harness.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <tuple>
#include <utility>
#include <vector>

#include <sys/resource.h>

#include "vk/pipeline.hpp"
#include "vk/transfer.hpp"

namespace dvs::bench {

std::vector<Registered>& registry() {
  static std::vector<Registered> r;
  return r;
}

double cpu_seconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

double gflop_per_cpu_second(const std::function<void()>& fn, double flops) {
  fn();  // warm
  int reps = 0;
  double c0 = cpu_seconds(), used = 0;
  do {
    fn();
    ++reps;
    used = cpu_seconds() - c0;
  } while (used < 0.5 && reps < 100);
  return flops * reps / (used * 1e9);
}

namespace {
constexpr uint32_t kPeakIters = 8192, kPeakGroups = 512, kPeakInvocations = kPeakGroups * 64;

void record_fma_peak(vk::Context& ctx, vk::Recorder& rec, const vk::Buffer& out, uint32_t chains, uint32_t unroll) {
  const uint32_t spec[] = {kPeakIters, chains, unroll};  // ITERS, CHAINS, UNROLL
  const float push[2] = {0.999f, 1e-3f};
  rec.begin();
  rec.dispatch(ctx.pipelines().get("bench/fma_peak", spec), {out.view()}, push, sizeof push, kPeakGroups);
  rec.end();
}

double fma_peak_flops(uint32_t chains) { return double(kPeakInvocations) * kPeakIters * chains * 4 * 2; }
}  // namespace

// The peak is the fastest of a few shapes of the shader: which one a driver runs best differs (measured,
// GFLOP per CPU-second: Mesa 22.3 best at 3 chains x 32 (86) where 2 x 64 gives 70; Mesa 25.0 best at 2 x 64
// (71) where 3 x 32 gives 31, so one fixed shape made 25.0's peak look a third of 22.3's). DVS_FMA_PEAK=
// "chains,unroll" measures that one shape only.
FmaPeakRun::FmaPeakRun(vk::Context& ctx) : recorder(ctx) {
  out = ctx.allocator().allocate(kPeakInvocations * 4);
  std::vector<std::pair<uint32_t, uint32_t>> shapes = {{3, 32}, {2, 64}, {2, 32}, {3, 16}, {4, 16}};
  if (const char* env = std::getenv("DVS_FMA_PEAK")) {
    unsigned c = 0, u = 0;
    char tail = 0;
    if (std::sscanf(env, "%u,%u%c", &c, &u, &tail) != 2 || c < 1 || c > 16 || u < 1 || u > 256 || kPeakIters % u != 0) {
      std::cerr << "DVS_FMA_PEAK must be chains,unroll (chains 1-16, unroll 1-256 dividing " << kPeakIters << "), got '"
                << env << "'\n";
      std::exit(2);
    }
    shapes = {{c, u}};
  }
  std::tie(chains, unroll) = shapes[0];
  double best = 0;
  for (size_t i = 0; shapes.size() > 1 && i < shapes.size(); ++i) {  // one shape: nothing to compare
    auto [c, u] = shapes[i];
    vk::Recorder trial(ctx);
    record_fma_peak(ctx, trial, out, c, u);
    const double rate = fma_peak_flops(c) / Bench::time_ms([&] { trial.submit(); }, 0.15);
    if (rate > best) best = rate, chains = c, unroll = u;
  }
  record_fma_peak(ctx, recorder, out, chains, unroll);
  flops = fma_peak_flops(chains);
}

CopyRun::CopyRun(vk::Context& ctx) : recorder(ctx) {
  // 64 MiB, or one binding / allocation where DVS_LIMITS forces them lower.
  const uint64_t n = std::min<uint64_t>({64ull << 20, ctx.caps().max_storage_buffer_range / 16 * 16,
                                         ctx.allocator().max_allocation() / 16 * 16});
  src = ctx.allocator().allocate(n);
  dst = ctx.allocator().allocate(n);
  ctx.transfer().fill_zero(src.view());
  recorder.begin();
  const uint32_t n4 = uint32_t(n / 16);
  recorder.dispatch(ctx.pipelines().get("bench/copy"), {src.view(), dst.view()}, &n4, 4, std::min({4096u, (n4 + 63) / 64, ctx.caps().max_workgroup_count[0]}));
  recorder.end();
  bytes = 2.0 * double(n);
}

double CopyRun::gbps(double min_seconds) { return bytes / (Bench::time_ms([&] { recorder.submit(); }, min_seconds) * 1e6); }

Registration::Registration(const char* group, int order, BenchFn fn) { registry().push_back({group, order, fn}); }

double Bench::time_ms(const std::function<void()>& fn, double min_seconds) {
  using clock = std::chrono::steady_clock;
  fn();  // warm-up: pipeline compilation, first-touch of memory
  std::vector<double> t;
  auto start = clock::now();
  while (t.size() < 3 || (std::chrono::duration<double>(clock::now() - start).count() < min_seconds && t.size() < 1000)) {
    auto a = clock::now();
    fn();
    t.push_back(std::chrono::duration<double, std::milli>(clock::now() - a).count());
  }
  std::nth_element(t.begin(), t.begin() + t.size() / 2, t.end());
  return t[t.size() / 2];
}

void Bench::report(Result r) {
  char line[512];
  std::string rate;
  if (r.gflops > 0) {
    char b[160];
    std::snprintf(b, sizeof b, "%9.2f GFLOP/s", r.gflops);
    rate = b;
    if (limits_.fma_peak_gflops > 0) {
      std::snprintf(b, sizeof b, "  %.2fx peak", r.gflops / limits_.fma_peak_gflops);
      rate += b;
    }
    if (limits_.sgemm_gflops > 0) {
      std::snprintf(b, sizeof b, "  %.2fx openblas", r.gflops / limits_.sgemm_gflops);
      rate += b;
    }
  } else if (r.gbps > 0) {
    char b[160];
    std::snprintf(b, sizeof b, "%9.2f GB/s", r.gbps);
    rate = b;
    if (limits_.copy_gbps > 0) {
      std::snprintf(b, sizeof b, "  %.2fx copy", r.gbps / limits_.copy_gbps);
      rate += b;
    }
  }
  std::snprintf(line, sizeof line, "%-28s %-22s %10.3f ms  %s%s%s\n", r.op.c_str(), r.shape.c_str(), r.ms, rate.c_str(),
                r.note.empty() ? "" : "  # ", r.note.c_str());
  std::cout << line << std::flush;
  results_.push_back(std::move(r));
}

void Bench::print_json() const {
  for (const Result& r : results_) {
    std::string j = "{\"op\":\"" + r.op + "\",\"shape\":\"" + r.shape + "\"";
    char b[128];
    std::snprintf(b, sizeof b, ",\"ms\":%.4f", r.ms);
    j += b;
    if (r.gflops > 0) {
      std::snprintf(b, sizeof b, ",\"gflops\":%.3f", r.gflops);
      j += b;
      if (limits_.fma_peak_gflops > 0) {
        std::snprintf(b, sizeof b, ",\"ratio_peak\":%.3f", r.gflops / limits_.fma_peak_gflops);
        j += b;
      }
      if (limits_.sgemm_gflops > 0) {
        std::snprintf(b, sizeof b, ",\"ratio_openblas\":%.3f", r.gflops / limits_.sgemm_gflops);
        j += b;
      }
    }
    if (r.gbps > 0) {
      std::snprintf(b, sizeof b, ",\"gbps\":%.3f", r.gbps);
      j += b;
      if (limits_.copy_gbps > 0) {
        std::snprintf(b, sizeof b, ",\"ratio_copy\":%.3f", r.gbps / limits_.copy_gbps);
        j += b;
      }
    }
    std::cout << j << "}\n";
  }
}

}  // namespace dvs::bench
