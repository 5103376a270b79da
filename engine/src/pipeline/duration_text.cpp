#include "dvs/duration_text.hpp"

#include <cmath>
#include <cstdio>

namespace dvs {

std::string duration_text(double s) {
  char buf[48];
  if (!std::isfinite(s) || s < 0) s = 0;
  if (s < 9.995) std::snprintf(buf, sizeof buf, "%.2f s", s);
  else if (s < 59.95) std::snprintf(buf, sizeof buf, "%.1f s", s);
  else if (s < 3599.5) {
    const long t = std::lround(s);
    std::snprintf(buf, sizeof buf, "%ld min %02ld s", t / 60, t % 60);
  } else {
    const long t = std::lround(s / 60);
    std::snprintf(buf, sizeof buf, "%ld h %02ld min", t / 60, t % 60);
  }
  return buf;
}

std::string count_text(long long n, const std::string& singular, const std::string& plural) {
  return std::to_string(n) + " " + (n == 1 ? singular : plural);
}

}  // namespace dvs
