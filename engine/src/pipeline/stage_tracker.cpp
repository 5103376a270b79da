#include "pipeline/stage_tracker.hpp"

namespace dvs {

StageTracker::StageTracker(const ProgressFn& progress, const CancelFn& cancelled)
    : progress_(progress), cancelled_(cancelled) {}

void StageTracker::begin(const std::string& stage, const std::string& note) {
  check_cancelled();
  stage_ = stage;
  start_ = std::chrono::steady_clock::now();
  say(0, 0, note);
}

void StageTracker::end() {
  times_.push_back({stage_, std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count()});
}

void StageTracker::say(int step, int total, const std::string& note) const {
  if (progress_) progress_(stage_, step, total, note);
}

bool StageTracker::cancel_requested() const { return cancelled_ && cancelled_(); }

void StageTracker::check_cancelled() const {
  if (cancel_requested()) throw Cancelled();
}

diffusion::LoopCallbacks StageTracker::loop_callbacks() const {
  diffusion::LoopCallbacks cb;
  cb.progress = [this](int step, int total, int t) { say(step, total, "t=" + std::to_string(t)); };
  cb.cancelled = [this] { return cancel_requested(); };
  return cb;
}

}  // namespace dvs
