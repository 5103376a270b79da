// Progress output for long commands: a bar per stage with step counts and ETA on a terminal, one JSON
// object per event with --progress json, nothing with --quiet.
#pragma once
#include <chrono>
#include <string>

namespace dvs::cli {

enum class ProgressMode { bar, json, quiet };

class Progress {
 public:
  explicit Progress(ProgressMode mode);
  ~Progress() { finish(); }  // ends an open bar line when a job stops early
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;
  void operator()(const std::string& stage, int step, int total, const std::string& note);
  void finish();

 private:
  ProgressMode mode_;
  bool tty_;
  std::string stage_;
  std::chrono::steady_clock::time_point stage_start_;
  bool open_line_ = false;
};

ProgressMode parse_progress_mode(const std::string& value, bool quiet);

}  // namespace dvs::cli
