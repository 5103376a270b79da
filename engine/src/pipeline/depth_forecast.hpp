// Before a long depth estimate, what it will cost: the FLOPs of every window (vda_cost.hpp) over the rate the
// device showed on the first encoder blocks of the first frames, and what would make it cheaper (a smaller
// network input; fewer frames when the clip needs more than one window). Said once, as soon as the rate is known.
#pragma once
#include <cstdint>
#include <optional>
#include <string>

#include "models/vda/vda_cost.hpp"
#include "models/vda/vda_video.hpp"
#include "spec/vda_config.hpp"

namespace dvs {

struct DepthForecastInput {
  VdaConfig cfg;
  int64_t frame_height = 0, frame_width = 0;  // the frames' size (after max_res)
  int input_size = 518;
  int windows = 1;
  std::string input_size_option, frames_option;  // how the advice names them (FramesDepthOptions)
  double threshold_s = 60;  // say nothing for estimates expected to take less
};

class DepthForecast {
 public:
  explicit DepthForecast(DepthForecastInput in);
  // At every step of the estimate, with the seconds since the first window's forward began: the forecast, once,
  // when the device's rate is known and the whole estimate is expected to take threshold_s or more.
  std::optional<std::string> on_step(const VdaStep& step, double seconds);
  // The expected seconds of the whole estimate (0 until the rate is known).
  double expected_seconds() const { return expected_s_; }

 private:
  double seconds_for(int input_size, int windows) const;

  DepthForecastInput in_;
  int64_t chunk_frames_ = 1;      // frames per encoder chunk (VdaModel::kEncoderChunkFrames)
  int measure_step_ = 1;          // the step at which the rate is taken
  double first_step_s_ = 0, rate_ = 0, expected_s_ = 0;
  bool said_ = false;
};

}  // namespace dvs
