// Video-Depth-Anything on a whole clip, as infer_video_depth does it: every frame preprocessed to the model size,
// windows of infer_len frames (key frames carried over from the previous window), one forward per window, its
// disparity resized bilinearly (align_corners) to the frame size, and the windows stitched (vda_stitch.hpp).
#pragma once
#include <array>
#include <functional>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "io/host_tensor.hpp"
#include "models/vda/vda_model.hpp"
#include "models/vda/vda_preprocess.hpp"

namespace dvs {

// Where the estimate stands inside a window (VdaModel::StepHook), for progress within long windows.
struct VdaStep {
  int window = 0, windows = 0;  // 1-based window index, and the clip's window count
  int done = 0, total = 0;      // steps of this window's forward
  std::string what;             // "encoder block 3/12, frames 1-4", "head temporal module 2/4", ...
};

struct VdaVideoOptions {
  int input_size = 518;  // VDA's --input_size
  // After each window's forward: its index and the number of windows (progress bars).
  std::function<void(int window, int windows)> on_window;
  // After every step of a window's forward (may throw dvs::Cancelled to stop there).
  std::function<void(const VdaStep&)> on_step;
  // For tests: each window's clip frame indices, its disparity at the model size [T, h, w] and at the frame size
  // [T, H, W], before alignment.
  std::function<void(int window, const std::vector<int64_t>& frames, const HostTensor& model_size,
                     const HostTensor& frame_size)>
      probe;
};

struct VdaVideoResult {
  HostTensor depth;                               // f32 [L, H, W] disparity (>= 0) at the frames' size
  VdaInputSize input;                             // the network input size used
  std::vector<std::array<float, 2>> scale_shift;  // per window after the first
};

// A window's disparity that no sound model gives: NaN/Inf, or one value everywhere (what NaN weights give after
// the final ReLU). The message names the window; the caller knows the model file.
struct VdaBrokenOutput : Error {
  using Error::Error;
};

// frames: u8 RGB [L, H, W, 3]. Throws VdaBrokenOutput for a broken window: such an estimate is never returned.
VdaVideoResult vda_video_depth(VdaModel& model, const HostTensor& frames, const VdaVideoOptions& options = {});

}  // namespace dvs
