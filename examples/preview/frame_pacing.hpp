// The preview's clock: motion is per second of wall time, not per displayed frame (a key held for 1 s flies the
// same distance at 20 or 400 frames a second), and frames are capped at a rate (--max-fps) so presents do not run
// unthrottled where the present mode does not wait (IMMEDIATE, MAILBOX, or FIFO under a virtual display).
#pragma once
#include <chrono>

namespace preview {

class FramePacer {
 public:
  // max_fps ≤ 0: no cap.
  explicit FramePacer(double max_fps);
  // Called at the start of each frame: waits until 1/max_fps has passed since the previous frame began, then says
  // how many seconds the frame stands for (the wall time since the previous frame began; at most kLongestStep, so a
  // stall, e.g. the window being dragged, does not fling the camera; the first frame: one frame period).
  double begin_frame();
  static constexpr double kLongestStep = 0.1;

 private:
  using Clock = std::chrono::steady_clock;
  Clock::duration period_{};
  Clock::time_point last_{};
  bool started_ = false;
};

}  // namespace preview
