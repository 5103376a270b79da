#include "io/crash_points.hpp"

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <string>

namespace dvs {
namespace {

struct CrashSwitch {
  bool active = false;
  long crash_at = 0;  // 0: never
  int trace_fd = -1;
  std::atomic<long> reached{0};

  CrashSwitch() {
    if (const char* at = std::getenv("DVS_CRASH_AT"); at && *at) crash_at = std::strtol(at, nullptr, 10);
    if (const char* trace = std::getenv("DVS_CRASH_TRACE"); trace && *trace)
      // O_APPEND: one write() per line, so lines of processes sharing a trace do not interleave; the kernel keeps
      // what was written even when SIGKILL follows at once.
      trace_fd = ::open(trace, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    active = crash_at > 0 || trace_fd >= 0;
  }
};

CrashSwitch& crash_switch() {
  static CrashSwitch s;
  return s;
}

}  // namespace

void crash_point(std::string_view kind, std::string_view detail, long number) {
  CrashSwitch& s = crash_switch();
  if (!s.active) return;
  const long n = ++s.reached;
  if (s.trace_fd >= 0) {
    std::string line = std::to_string(n);
    line += ' ';
    line.append(kind);
    if (!detail.empty()) line.append(1, ':').append(detail);
    if (number >= 0) line.append(1, ':').append(std::to_string(number));
    line += '\n';
    [[maybe_unused]] const ssize_t w = ::write(s.trace_fd, line.data(), line.size());
  }
  if (n == s.crash_at) ::raise(SIGKILL);
}

}  // namespace dvs
