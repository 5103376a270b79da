// Video-Depth-Anything's per-frame preprocessing, as infer_video_depth does it: the model input size for a frame
// size (the aspect-ratio rule, then "lower bound, keep aspect ratio, multiple of 14"), OpenCV's cubic resize of
// the frame in float32, ImageNet normalisation evaluated in double and stored as float, HWC -> CHW.
#pragma once
#include <cstdint>

#include "spec/vda_config.hpp"

namespace dvs {

struct VdaInputSize {
  int64_t height = 0, width = 0;
};

// The network input size infer_video_depth picks for a frame_h x frame_w clip and its input_size argument
// (multiples of `multiple`, the patch size). Throws dvs::Error for sizes it cannot handle (< 1).
VdaInputSize vda_input_size(int64_t frame_h, int64_t frame_w, int input_size, int multiple = 14);

// One u8 RGB frame [frame_h, frame_w, 3] -> f32 [3, size.height, size.width] at `out`.
void vda_preprocess_frame(const uint8_t* rgb, int64_t frame_h, int64_t frame_w, VdaInputSize size, const VdaConfig& cfg,
                          float* out);

}  // namespace dvs
