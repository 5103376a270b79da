// What a running process holds, read from /proc/PID: resident memory now and its peak (VmRSS, VmHWM), threads
// and open file descriptors; and resetting the peak (clear_refs "5"), so that each job's own peak can be read.
// For the long-run tests: a leak of memory, threads or files grows these job after job.
#pragma once
#include <sys/types.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace dvs::test {

struct ProcessMemory {
  uint64_t rss_bytes = 0;       // VmRSS
  uint64_t peak_rss_bytes = 0;  // VmHWM: since the process started or the last reset_peak_rss
  int threads = 0;
  int open_files = 0;           // entries of /proc/PID/fd
  bool valid = false;           // false when the process is gone
};

// /proc/PID/status's "Key:   N kB" (or a plain count for Threads); -1 when the key is missing.
inline int64_t proc_status_value(const std::string& status, const std::string& key) {
  const auto at = status.find("\n" + key + ":");
  if (at == std::string::npos) return -1;
  return std::stoll(status.substr(at + key.size() + 2));
}

inline ProcessMemory process_memory(pid_t pid) {
  ProcessMemory m;
  const std::filesystem::path proc = "/proc/" + std::to_string(pid);
  std::ifstream in(proc / "status");
  const std::string status = "\n" + std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  const int64_t rss = proc_status_value(status, "VmRSS"), hwm = proc_status_value(status, "VmHWM"),
                threads = proc_status_value(status, "Threads");
  if (rss < 0 || hwm < 0 || threads < 0) return m;  // gone, or a zombie (no memory lines)
  m.rss_bytes = uint64_t(rss) * 1024;
  m.peak_rss_bytes = uint64_t(hwm) * 1024;
  m.threads = int(threads);
  std::error_code ec;
  for (std::filesystem::directory_iterator it(proc / "fd", ec), end; !ec && it != end; it.increment(ec)) ++m.open_files;
  m.valid = !ec;
  return m;
}

// Restarts VmHWM from the current VmRSS (Linux ≥ 4.0; the process's owner or root). False when refused.
inline bool reset_peak_rss(pid_t pid) {
  std::ofstream out("/proc/" + std::to_string(pid) + "/clear_refs");
  out << "5";
  out.flush();
  return bool(out);
}

// Host memory a job may add over the second job's. What varies without a leak stays well under it (under 1.5
// MiB measured: Mesa's and glibc's caches); a leak of one job's working set (its tensors and frames, several
// MiB even at 64×64) or of a Vulkan device (tens of MiB on lavapipe) does not, nor does a leak of 0.4 MiB a job
// over the 10 jobs compared.
constexpr uint64_t kGrowthBound = 4ull << 20;

// glibc's malloc raises its mmap threshold each time a large mapped block is freed, so over the first jobs the
// same sizes move from their own mappings (returned to the system when freed) to the heap (kept resident): RSS
// then climbs about 5 MiB over jobs 2-6 and stays there, which is glibc's choice, not memory dvs holds. A fixed
// threshold (glibc's default starting value) turns that off; the tests measure with it.
constexpr const char* kFixedMmapThreshold = "GLIBC_TUNABLES=glibc.malloc.mmap_threshold=131072";
constexpr int kFixedMmapThresholdBytes = 131072;

inline double mib(uint64_t bytes) { return double(bytes) / (1024.0 * 1024.0); }

}  // namespace dvs::test
