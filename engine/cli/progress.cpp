#include "progress.hpp"

#include <unistd.h>

#include <cstdio>
#include <nlohmann/json.hpp>

#include "args.hpp"

namespace dvs::cli {

ProgressMode progress_mode(const Args& a) {
  const std::string value = a.str("progress", "bar");
  if (value != "bar" && value != "json" && value != "none") a.fail("--progress must be bar, json or none, got '" + value + "'");
  // --quiet is --progress none: with another mode the two contradict each other.
  if (a.has("quiet") && a.has("progress") && value != "none")
    a.fail("--quiet and --progress " + value + " contradict each other; give one of them");
  if (a.has("quiet") || value == "none") return ProgressMode::quiet;
  return value == "json" ? ProgressMode::json : ProgressMode::bar;
}

Progress::Progress(ProgressMode mode) : mode_(mode), tty_(isatty(fileno(stderr))) {}

void Progress::operator()(const std::string& stage, int step, int total, const std::string& note) {
  auto now = std::chrono::steady_clock::now();
  if (stage != stage_) {
    finish();
    stage_ = stage;
    stage_start_ = now;
  }
  double elapsed = std::chrono::duration<double>(now - stage_start_).count();
  // Warnings (a damaged cache entry recomputed, a cache that cannot be written) are not progress: the library sends
  // them to the log handler main() installs, which prints them in every mode.
  if (mode_ == ProgressMode::quiet) return;
  if (mode_ == ProgressMode::json) {
    emit_json_event({{"event", "progress"}, {"stage", stage}, {"step", step}, {"total", total}, {"elapsed_s", elapsed},
                     {"note", note}});
    return;
  }
  std::string line;
  char buf[256];
  if (total > 0) {
    const int width = 24, filled = width * step / total;
    double eta = step > 0 ? elapsed / step * (total - step) : 0;
    std::snprintf(buf, sizeof buf, "%-10s [%s%s] %d/%d  %.1fs, ETA %.1fs  %s", stage.c_str(),
                  std::string(size_t(filled), '#').c_str(), std::string(size_t(width - filled), '.').c_str(), step, total,
                  elapsed, eta, note.c_str());
  } else {
    std::snprintf(buf, sizeof buf, "%-10s %s", stage.c_str(), note.c_str());
  }
  line = buf;
  if (tty_) {
    std::fprintf(stderr, "\r\033[K%s", line.c_str());
    open_line_ = true;
  } else {
    std::fprintf(stderr, "%s\n", line.c_str());
  }
  std::fflush(stderr);
}

void Progress::finish() {
  if (open_line_) std::fprintf(stderr, "\n");
  open_line_ = false;
}

}  // namespace dvs::cli

namespace dvs::cli {

void emit_json_event(const nlohmann::json& event) {
  // C stdio, not std::cout: with --progress json, main points std::cout at stderr so that plain lines never
  // mix into the JSON Lines on stdout.
  std::fprintf(stdout, "%s\n", event.dump().c_str());
  std::fflush(stdout);
}

bool wants_json_progress(const std::vector<std::string>& args) {
  for (size_t i = 0; i < args.size(); ++i) {
    if (args[i] == "--progress=json") return true;
    if (args[i] == "--progress" && i + 1 < args.size() && args[i + 1] == "json") return true;
  }
  return false;
}

}  // namespace dvs::cli
