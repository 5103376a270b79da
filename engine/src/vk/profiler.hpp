// GPU time per op label, from timestamps the Recorder writes around each dispatch when profiling is on
// (DVS_PROFILE=1). Printed as a table when the context closes.
#pragma once
#include <cstdint>
#include <map>
#include <string>

namespace dvs::vk {

class Profiler {
 public:
  explicit Profiler(bool enabled) : enabled_(enabled) {}
  bool enabled() const { return enabled_; }
  void set_enabled(bool on) { enabled_ = on; }
  void add(const std::string& label, double ns);
  struct Entry {
    uint64_t count = 0;
    double total_ns = 0;
  };
  const std::map<std::string, Entry>& entries() const { return entries_; }
  void clear() { entries_.clear(); }
  std::string report() const;  // table sorted by total time
  void print_if_enabled() const;

 private:
  bool enabled_;
  std::map<std::string, Entry> entries_;
};

}  // namespace dvs::vk
