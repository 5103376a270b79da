#include "args.hpp"

#include <cmath>
#include <sstream>

#include "dvs/error.hpp"
#include "dvs/usage_error.hpp"

namespace dvs::cli {

Args::Args(std::string command, const std::vector<std::string>& argv, const std::set<std::string>& options,
           const std::set<std::string>& flags)
    : command_(std::move(command)) {
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (a == "-h" || a == "--help") {
      help_ = true;
      continue;
    }
    if (a.rfind("--", 0) != 0) fail("unexpected argument '" + a + "'");
    std::string name = a.substr(2), value;
    bool inline_value = false;
    if (auto eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
      inline_value = true;
    }
    if (flags.count(name)) {
      if (inline_value) fail("--" + name + " takes no value");
      flags_.insert(name);
    } else if (options.count(name)) {
      if (!inline_value) {
        if (i + 1 >= argv.size()) fail("--" + name + " needs a value");
        value = argv[++i];
      }
      values_[name] = value;
    } else {
      fail("unknown option --" + name);
    }
  }
}

void Args::fail(const std::string& what) const {
  throw UsageError("dvs " + command_ + ": " + what + " (see dvs " + command_ + " --help)");
}

std::string Args::str(const std::string& name, const std::string& fallback) const {
  auto it = values_.find(name);
  return it == values_.end() ? fallback : it->second;
}

std::string Args::required(const std::string& name) const {
  auto it = values_.find(name);
  if (it == values_.end() || it->second.empty()) fail("--" + name + " is required");
  return it->second;
}

int Args::integer(const std::string& name, int fallback, int lo, int hi) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  try {
    size_t used = 0;
    long v = std::stol(it->second, &used);
    if (used != it->second.size()) throw std::invalid_argument("");
    if (v < lo || v > hi) fail("--" + name + " must be between " + std::to_string(lo) + " and " + std::to_string(hi));
    return int(v);
  } catch (const std::logic_error&) {
    fail("--" + name + " must be a whole number, got '" + it->second + "'");
  }
}

double Args::number(const std::string& name, double fallback) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  try {
    size_t used = 0;
    double v = std::stod(it->second, &used);
    if (used != it->second.size() || !std::isfinite(v)) throw std::invalid_argument("");
    return v;
  } catch (const std::logic_error&) {
    fail("--" + name + " must be a number, got '" + it->second + "'");
  }
}

std::pair<int, int> Args::size(const std::string& name, std::pair<int, int> fallback) const {
  auto it = values_.find(name);
  if (it == values_.end()) return fallback;
  int h = 0, w = 0;
  char x = 0, extra = 0;
  std::istringstream in(it->second);
  if (!(in >> h >> x >> w) || (x != 'x' && x != 'X') || (in >> extra) || h <= 0 || w <= 0)
    fail("--" + name + " must look like HEIGHTxWIDTH, e.g. 480x720, got '" + it->second + "'");
  return {h, w};
}

std::pair<int, int> Args::working_size(std::pair<int, int> fallback) const {
  const bool dims = has("height") || has("width");
  if (has("size") && dims) fail("give either --size HxW or --height H --width W, not both");
  if (!dims) return size("size", fallback);
  if (!has("height") || !has("width")) fail("--height and --width go together (or use --size HxW)");
  return {integer("height", 0, 8, 1 << 16), integer("width", 0, 8, 1 << 16)};
}

std::vector<double> Args::numbers(const std::string& name, size_t count) const {
  std::vector<double> out;
  std::string s = str(name);
  std::stringstream ss(s);
  for (std::string part; std::getline(ss, part, ',');) {
    try {
      size_t used = 0;
      out.push_back(std::stod(part, &used));
      if (used != part.size()) throw std::invalid_argument("");
    } catch (const std::logic_error&) {
      fail("--" + name + " must be " + std::to_string(count) + " comma-separated numbers, got '" + s + "'");
    }
  }
  if (out.size() != count) fail("--" + name + " must be " + std::to_string(count) + " comma-separated numbers, got '" + s + "'");
  return out;
}

}  // namespace dvs::cli
