#include "harness.hpp"

#include <algorithm>
#include <cstdio>
#include <iostream>

namespace dvs::bench {

std::vector<Registered>& registry() {
  static std::vector<Registered> r;
  return r;
}

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
