#include "pipeline/stage_tracker.hpp"

#include <memory>

#include "io/crash_points.hpp"
#include "io/injected_faults.hpp"

namespace dvs {

const char* const kNonFiniteHint =
    "the run is stopped rather than writing a black video. Usual causes: a weight file holding NaN/Inf "
    "(dvs-weights inspect --values MODEL lists them), a damaged input, or an overflow (16-bit arithmetic)";

StageTracker::StageTracker(const ProgressFn& progress, const CancelFn& cancelled)
    : progress_(progress), cancelled_(cancelled) {}

void StageTracker::begin(const std::string& stage, const std::string& note) {
  check_cancelled();
  crash_point("stage-begin", stage);
  stage_ = stage;
  ended_ = false;
  faults::set_stage(stage);  // named in DVS_FAULTS_TRACE's lines
  start_ = std::chrono::steady_clock::now();
  say(0, 0, note);
}

void StageTracker::end() {
  crash_point("stage-end", stage_);
  ended_ = true;
  faults::set_stage("after-" + stage_);
  times_.push_back({stage_, std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count()});
}

void StageTracker::say(int step, int total, const std::string& note) const {
  last_step_ = step;
  last_total_ = total;
  last_note_ = note;
  if (progress_) progress_(stage_, step, total, note);
}

vk::SegmentHook StageTracker::segment_hook() const {
  auto last = std::make_shared<std::chrono::steady_clock::time_point>(std::chrono::steady_clock::now());
  return [this, last](const vk::SegmentProgress& p) {
    check_cancelled();
    const auto now = std::chrono::steady_clock::now();
    if (!progress_ || std::chrono::duration<double>(now - *last).count() < kSegmentProgressS) return;
    *last = now;
    // Inside a stepped loop the work belongs to the step after the last one reported.
    const std::string note = last_total_ > 0 ? "step " + std::to_string(last_step_ + 1) + ": " + p.label
                             : last_note_.empty() ? p.label
                                                  : last_note_ + " · " + p.label;
    progress_(stage_, last_step_, last_total_, note);
  };
}

std::string StageTracker::where() const {
  if (stage_.empty()) return "start-up";
  return ended_ ? "after the " + stage_ + " stage" : stage_ + " stage";
}

bool StageTracker::cancel_requested() const { return cancelled_ && cancelled_(); }

void StageTracker::check_cancelled() const {
  if (cancel_requested()) throw Cancelled();
}

diffusion::LoopCallbacks StageTracker::loop_callbacks(ops::NonFiniteCheck* check) const {
  diffusion::LoopCallbacks cb;
  cb.progress = [this, check](int step, int total, int t) {
    if (check) {  // the step's recording has run: its scans are final
      const auto hits = check->hits();
      if (!hits.empty()) throw Error(hits.front().message() + "; " + kNonFiniteHint);
      check->clear();
    }
    say(step, total, "t=" + std::to_string(t));
    crash_point("step", stage_, step);
  };
  cb.cancelled = [this] { return cancel_requested(); };
  return cb;
}

}  // namespace dvs
