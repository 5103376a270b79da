// The library called in a loop stays flat: run_pipeline (the whole job) and render_novel_view (the render alone)
// called again and again in this process on the conformance pack's tiny model and the synthetic scene. After
// the second call nothing may grow: this process's RSS after a call and its peak during a call (VmHWM,
// restarted before each call) within test::kGrowthBound of the second call's, threads and open files exactly,
// and each run's device-memory peak (RunReport::peak_device_bytes, the allocator's) exactly. Label "robustness".
#include <gtest/gtest.h>
#include <malloc.h>
#include <unistd.h>

#include <cstdio>
#include <functional>
#include <vector>

#include "dvs/pipeline.hpp"
#include "dvs/render.hpp"
#include "flat_memory/process_memory.hpp"
#include "support/pipeline_inputs.hpp"

namespace dvs {
namespace {

struct CallSample {
  test::ProcessMemory after;  // right after the call returned; its peak_rss_bytes is the call's own peak
  uint64_t device_peak = 0;   // 0 where the call does not report it
};

// Calls `call(i)` `calls` times, sampling this process after each; prints the table.
std::vector<CallSample> sample_calls(int calls, const std::function<uint64_t(int)>& call) {
  mallopt(M_MMAP_THRESHOLD, test::kFixedMmapThresholdBytes);  // see kFixedMmapThreshold
  std::vector<CallSample> samples;
  for (int i = 0; i < calls; ++i) {
    EXPECT_TRUE(test::reset_peak_rss(getpid())) << "/proc/self/clear_refs refused: the peaks would not be per call";
    const uint64_t device_peak = call(i);
    malloc_trim(0);  // free memory glibc keeps in its arenas is not held by the library
    samples.push_back({test::process_memory(getpid()), device_peak});
    EXPECT_TRUE(samples.back().after.valid);
  }
  std::printf("call  RSS after (MiB)  peak RSS (MiB)  threads  open files  device peak (MiB)\n");
  for (size_t i = 0; i < samples.size(); ++i) {
    const CallSample& s = samples[i];
    std::printf("%4zu  %15.2f  %14.2f  %7d  %10d  %17.2f\n", i + 1, test::mib(s.after.rss_bytes),
                test::mib(s.after.peak_rss_bytes), s.after.threads, s.after.open_files, test::mib(s.device_peak));
  }
  return samples;
}

void expect_flat_after_second_call(const std::vector<CallSample>& samples) {
  ASSERT_GE(samples.size(), 3u);
  const CallSample& second = samples[1];
  for (size_t i = 2; i < samples.size(); ++i) {
    const CallSample& s = samples[i];
    EXPECT_LE(s.after.rss_bytes, second.after.rss_bytes + test::kGrowthBound)
        << "call " << i + 1 << " left " << test::mib(s.after.rss_bytes - second.after.rss_bytes)
        << " MiB more resident than call 2";
    EXPECT_LE(s.after.peak_rss_bytes, second.after.peak_rss_bytes + test::kGrowthBound)
        << "call " << i + 1 << "'s peak RSS is " << test::mib(s.after.peak_rss_bytes - second.after.peak_rss_bytes)
        << " MiB over call 2's";
    EXPECT_EQ(s.after.threads, second.after.threads) << "threads after call " << i + 1;
    EXPECT_EQ(s.after.open_files, second.after.open_files) << "open files after call " << i + 1;
    EXPECT_EQ(s.device_peak, second.device_peak) << "device memory peak of call " << i + 1;
  }
}

TEST(FlatMemory, RunPipelineInALoop) {
  test::PipelineInputs in;
  const auto samples = sample_calls(10, [&](int i) {
    RunOptions o = in.run_options(in.dir / ("out" + std::to_string(i)), in.cache);
    o.seed = uint64_t(i);  // the inversion comes from the cache after the first call, the sampling is new each time
    return run_pipeline(o).peak_device_bytes;
  });
  expect_flat_after_second_call(samples);
}

TEST(FlatMemory, RenderInALoop) {
  test::PipelineInputs in;
  const auto samples = sample_calls(16, [&](int i) {
    RenderJob job = in.run_options(in.dir / ("render" + std::to_string(i)), in.cache).render;
    render_novel_view(job);
    return uint64_t(0);
  });
  expect_flat_after_second_call(samples);
}

}  // namespace
}  // namespace dvs
