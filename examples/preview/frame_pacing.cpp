#include "frame_pacing.hpp"

#include <algorithm>
#include <thread>

namespace preview {

FramePacer::FramePacer(double max_fps) {
  if (max_fps > 0) period_ = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / max_fps));
}

double FramePacer::begin_frame() {
  Clock::time_point now = Clock::now();
  if (!started_) {
    started_ = true;
    last_ = now;
    return period_.count() ? std::chrono::duration<double>(period_).count() : 1.0 / 60.0;
  }
  if (period_.count() && now - last_ < period_) {
    std::this_thread::sleep_until(last_ + period_);
    now = Clock::now();
  }
  const double step = std::chrono::duration<double>(now - last_).count();
  last_ = now;
  return std::min(step, kLongestStep);
}

}  // namespace preview
