#include "io/injected_faults.hpp"

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <sstream>
#include <string>

#include "dvs/error.hpp"

namespace dvs::faults {
namespace {

struct Plan {
  bool active = false;  // DVS_FAULTS or DVS_FAULTS_TRACE set
  long fail_at[3] = {0, 0, 0};  // per Kind; 0 = never
  int write_errno = 0;
  std::string trace;  // DVS_FAULTS_TRACE
  std::atomic<long> count[3] = {0, 0, 0};
  std::mutex mutex;  // the stage name and the trace file
  std::string stage = "start-up";  // before the first stage
};

const char* kind_name(Kind k) { return k == Kind::alloc ? "alloc" : k == Kind::submit ? "submit" : "write"; }

[[noreturn]] void bad_spec(const std::string& item) {
  throw Error("DVS_FAULTS: '" + item + "' is not one of alloc=N, submit=N, write=N:ENOSPC, write=N:EIO (N ≥ 1, "
              "comma-separated); unset DVS_FAULTS to run without injected faults");
}

long parse_count(const std::string& text, const std::string& item) {
  char* end = nullptr;
  errno = 0;
  const long n = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || *end || errno || n < 1) bad_spec(item);
  return n;
}

Plan& plan() {
  static Plan* p = [] {
    auto* q = new Plan;  // never freed: hooks may run during static destruction
    const char* spec = std::getenv("DVS_FAULTS");
    const char* trace = std::getenv("DVS_FAULTS_TRACE");
    if (trace && *trace) q->trace = trace;
    q->active = (spec && *spec) || !q->trace.empty();
    std::stringstream items(spec ? spec : "");
    for (std::string item; std::getline(items, item, ',');) {
      if (item.empty()) continue;
      const size_t eq = item.find('=');
      if (eq == std::string::npos) bad_spec(item);
      const std::string key = item.substr(0, eq);
      std::string value = item.substr(eq + 1);
      if (key == "alloc") q->fail_at[int(Kind::alloc)] = parse_count(value, item);
      else if (key == "submit") q->fail_at[int(Kind::submit)] = parse_count(value, item);
      else if (key == "write") {
        const size_t colon = value.find(':');
        if (colon == std::string::npos) bad_spec(item);
        const std::string err = value.substr(colon + 1);
        if (err == "ENOSPC") q->write_errno = ENOSPC;
        else if (err == "EIO") q->write_errno = EIO;
        else bad_spec(item);
        q->fail_at[int(Kind::write)] = parse_count(value.substr(0, colon), item);
      } else {
        bad_spec(item);
      }
    }
    return q;
  }();
  return *p;
}

}  // namespace

bool fail_now(Kind kind, std::string_view where) {
  Plan& p = plan();
  if (!p.active) return false;
  const long n = ++p.count[int(kind)];
  const bool fail = n == p.fail_at[int(kind)];
  if (!p.trace.empty()) {
    std::lock_guard<std::mutex> lock(p.mutex);
    // Plain stdio, not a counted writer: the trace is not one of the writes it counts.
    if (FILE* f = std::fopen(p.trace.c_str(), "a")) {
      std::fprintf(f, "%s %ld stage=%s %.*s%s\n", kind_name(kind), n, p.stage.c_str(), int(where.size()), where.data(),
                   fail ? " FAILED" : "");
      std::fclose(f);
    }
  }
  return fail;
}

int write_error(const std::filesystem::path& file) {
  if (!plan().active) return 0;
  return fail_now(Kind::write, file.string()) ? plan().write_errno : 0;
}

void set_stage(std::string_view stage) {
  Plan& p = plan();
  if (!p.active) return;
  std::lock_guard<std::mutex> lock(p.mutex);
  p.stage = std::string(stage);
}

}  // namespace dvs::faults
