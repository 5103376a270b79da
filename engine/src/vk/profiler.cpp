#include "vk/profiler.hpp"

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <vector>

namespace dvs::vk {

void Profiler::add(const std::string& label, double ns) {
  Entry& e = entries_[label];
  e.count++;
  e.total_ns += ns;
}

std::string Profiler::report() const {
  std::vector<std::pair<std::string, Entry>> rows(entries_.begin(), entries_.end());
  std::sort(rows.begin(), rows.end(), [](auto& a, auto& b) { return a.second.total_ns > b.second.total_ns; });
  double total = 0;
  for (auto& r : rows) total += r.second.total_ns;
  std::string out = "GPU time per op (DVS_PROFILE=1)\n";
  char line[256];
  std::snprintf(line, sizeof line, "  %-40s %8s %12s %12s %6s\n", "op", "calls", "total ms", "mean us", "share");
  out += line;
  for (auto& [label, e] : rows) {
    std::snprintf(line, sizeof line, "  %-40s %8llu %12.3f %12.2f %5.1f%%\n", label.c_str(), (unsigned long long)e.count,
                  e.total_ns * 1e-6, e.total_ns * 1e-3 / double(e.count), total > 0 ? 100.0 * e.total_ns / total : 0.0);
    out += line;
  }
  std::snprintf(line, sizeof line, "  %-40s %8s %12.3f\n", "total", "", total * 1e-6);
  out += line;
  return out;
}

void Profiler::print_if_enabled() const {
  if (enabled_ && !entries_.empty()) std::cerr << report();
}

}  // namespace dvs::vk
