// Runtime costs: host<->device copy bandwidth and the fixed cost of a dispatch and of a submission.
#include <vector>

#include "harness.hpp"
#include "vk/pipeline.hpp"
#include "vk/recorder.hpp"
#include "vk/transfer.hpp"

namespace dvs::bench {
namespace {

void host_transfers(Bench& b) {
  vk::Context& ctx = b.ctx();
  const size_t bytes = 64u << 20;
  std::vector<uint8_t> host(bytes, 1);
  vk::Buffer dev = ctx.allocator().allocate(bytes);
  double up = Bench::time_ms([&] { ctx.transfer().upload(dev.view(), host.data(), bytes); });
  b.report({"upload_host_to_device", "64MiB", up, 0, double(bytes) / (up * 1e6),
            ctx.allocator().device_memory_is_mapped() ? "mapped memory" : "via staging"});
  double down = Bench::time_ms([&] { ctx.transfer().download(dev.view(), host.data(), bytes); });
  b.report({"download_device_to_host", "64MiB", down, 0, double(bytes) / (down * 1e6),
            ctx.allocator().device_memory_is_mapped() ? "mapped memory" : "via staging"});
}

void dispatch_cost(Bench& b) {
  vk::Context& ctx = b.ctx();
  const vk::Pipeline& p = ctx.pipelines().get("bench/empty");
  const int n = 1000;
  vk::Recorder rec(ctx);
  rec.begin();
  for (int i = 0; i < n; ++i) rec.dispatch(p, std::vector<vk::Binding>{}, nullptr, 0, 1);
  rec.end();
  double ms = Bench::time_ms([&] { rec.submit(); });
  b.report({"empty_dispatch", "1 group, 1000 per submit", ms / n, 0, 0, "per dispatch, recorded once"});

  vk::Recorder one(ctx);
  one.begin();
  one.dispatch(p, std::vector<vk::Binding>{}, nullptr, 0, 1);
  one.end();
  double sub = Bench::time_ms([&] { one.submit(); });
  b.report({"submit_and_wait", "1 empty dispatch", sub, 0, 0, "per submission"});

  double rerecord = Bench::time_ms([&] {
    one.begin();
    one.dispatch(p, std::vector<vk::Binding>{}, nullptr, 0, 1);
    one.end();
  });
  b.report({"record_dispatch", "1 dispatch", rerecord, 0, 0, "CPU cost to record (no submit)"});
}

void runtime(Bench& b) {
  host_transfers(b);
  dispatch_cost(b);
}

Registration reg("runtime", 1, runtime);

}  // namespace
}  // namespace dvs::bench
