// dvs-bench harness: benchmarks register themselves by group; each reports results that the harness
// prints as a table and, at the end, as one JSON line per result. The machine's own limits (fp32 FMA peak
// of the device, its shader copy bandwidth, OpenBLAS sgemm on the same threads) are measured in the same
// run so every figure comes with its ratio.
#pragma once
#include <chrono>
#include <functional>
#include <string>
#include <vector>

#include "vk/context.hpp"

namespace dvs::bench {

struct Result {
  std::string op, shape;
  double ms = 0;         // per call
  double gflops = 0;     // compute-bound ops
  double gbps = 0;       // memory-bound ops
  std::string note;
};

struct Limits {
  double fma_peak_gflops = 0;   // device, independent FMA chains
  double copy_gbps = 0;         // device, shader buffer copy
  double sgemm_gflops = 0;      // OpenBLAS on the host, same thread count (0 if unavailable)
};

class Bench {
 public:
  Bench(vk::Context& ctx, bool quick) : ctx_(ctx), quick_(quick) {}
  vk::Context& ctx() { return ctx_; }
  bool quick() const { return quick_; }
  Limits& limits() { return limits_; }
  void report(Result r);
  const std::vector<Result>& results() const { return results_; }
  void print_json() const;

  // Median wall time of `fn` in ms: one warm-up call, then repeats until ~min_seconds (at least 3 calls).
  static double time_ms(const std::function<void()>& fn, double min_seconds = 0.5);

 private:
  vk::Context& ctx_;
  bool quick_;
  Limits limits_;
  std::vector<Result> results_;
};

using BenchFn = void (*)(Bench&);
struct Registration {
  Registration(const char* group, int order, BenchFn fn);
};
struct Registered {
  const char* group;
  int order;  // limits (order 0) run before everything that is compared with them
  BenchFn fn;
};
std::vector<Registered>& registry();

}  // namespace dvs::bench
