// Video-Depth-Anything on a whole clip, as infer_video_depth does it: every frame preprocessed to the model size,
// windows of infer_len frames (key frames carried over from the previous window), one forward per window, its
// disparity resized bilinearly (align_corners) to the frame size, and the windows stitched (vda_stitch.hpp).
#pragma once
#include <array>
#include <functional>
#include <vector>

#include "io/host_tensor.hpp"
#include "models/vda/vda_model.hpp"
#include "models/vda/vda_preprocess.hpp"

namespace dvs {

struct VdaVideoOptions {
  int input_size = 518;  // VDA's --input_size
  // After each window's forward: its index and the number of windows (progress bars).
  std::function<void(int window, int windows)> on_window;
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

// frames: u8 RGB [L, H, W, 3].
VdaVideoResult vda_video_depth(VdaModel& model, const HostTensor& frames, const VdaVideoOptions& options = {});

}  // namespace dvs
