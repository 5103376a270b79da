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
#include "vk/memory.hpp"
#include "vk/recorder.hpp"

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
  double fma_peak_per_cpu_second = 0;  // the same shader, GFLOP per CPU-second of this process (CPU devices)
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

// CPU time of this process. On a CPU device (lavapipe) wall-clock rates swing with whatever else runs on the
// machine; work per CPU-second is far steadier, and its ratio to the FMA-peak shader's, measured the same way,
// is the figure to compare between runs.
double cpu_seconds();
// GFLOP per CPU-second of `fn` doing `flops` per call: one warm-up call, then calls until ~0.5 CPU-seconds.
double gflop_per_cpu_second(const std::function<void()>& fn, double flops);

// The FMA-peak shader (shaders/bench/fma_peak.comp) in the fastest of a few shapes on this device (chains x
// unroll), recorded once: `flops` per submit of `recorder`.
struct FmaPeakRun {
  FmaPeakRun(vk::Context& ctx);
  vk::Buffer out;
  vk::Recorder recorder;
  double flops = 0;
  uint32_t chains = 0, unroll = 0;
};

// The copy shader (shaders/bench/copy.comp) over 64 MiB, recorded once: `bytes` read + written per submit.
// Owned by the benchmark that uses it: Vulkan objects must go before the context.
struct CopyRun {
  CopyRun(vk::Context& ctx);
  vk::Buffer src, dst;
  vk::Recorder recorder;
  double bytes = 0;
  double gbps(double min_seconds = 0.3);  // timed now (the machine's load changes within a run)
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
