// dvs/info.hpp's bench_upload: the rate at which streamed weights reach the device (vk::UploadQueue), measured
// on the host clock around each upload and its wait (an upload is one copy command of `bytes`).
#include <algorithm>
#include <chrono>
#include <cstring>
#include <vector>

#include "dvs/info.hpp"
#include "vk/context.hpp"
#include "vk/memory.hpp"
#include "vk/upload_queue.hpp"

namespace dvs {

UploadBench bench_upload(const std::string& device_spec, uint64_t bytes, int uploads) {
  vk::ContextOptions options;
  options.device = device_spec;
  vk::Context ctx(options);
  UploadBench r;
  r.device = ctx.caps().name;
  r.queue = ctx.has_transfer_queue() ? "transfer-only family " + std::to_string(ctx.transfer_queue_family())
                                     : std::string("compute queue (the device has no transfer-only family)");
  r.bytes = std::min<uint64_t>(bytes, ctx.allocator().max_allocation());
  r.uploads = std::max(uploads, 1);
  vk::Buffer host = ctx.allocator().allocate(r.bytes, vk::MemoryUse::pinned, "upload benchmark (host)");
  vk::Buffer slot = ctx.allocator().allocate(r.bytes, vk::MemoryUse::device_shared, "upload benchmark (device)");
  std::memset(host.mapped(), 0x5a, size_t(r.bytes));
  vk::UploadQueue queue(ctx);
  std::vector<double> rates;
  for (int i = 0; i <= r.uploads; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    queue.wait(queue.upload(host.view(), slot.view(), r.bytes, ctx.submission_count()));
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (i > 0) rates.push_back(double(r.bytes) / s);  // the first one warms the queue up
  }
  std::sort(rates.begin(), rates.end());
  r.bytes_per_second = rates[rates.size() / 2];
  r.min_bytes_per_second = rates.front();
  r.max_bytes_per_second = rates.back();
  return r;
}

}  // namespace dvs
