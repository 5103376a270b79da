// Progress output for long commands: a bar per stage with step counts and ETA on a terminal, one JSON
// object per event with --progress json, nothing with --quiet; warnings in every mode.
#pragma once
#include <chrono>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "args.hpp"

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

// --progress bar|json|none and --quiet (= none); the two together with another mode are a usage error.
ProgressMode progress_mode(const Args& a);

// --progress json: one JSON object per line on stdout. Every event has "event": "progress" (a stage's step),
// then exactly one final "done" (exit_code 0) or "error" (message, exit_code 1, 2 or 130).
void emit_json_event(const nlohmann::json& event);

// Whether a command line asks for --progress json (main decides where plain lines go before parsing).
bool wants_json_progress(const std::vector<std::string>& args);

}  // namespace dvs::cli
