// The preview's frame and depth, read from the files the options name: the frame from a video (--video, through
// dvs's video component) or an .npy frame array, its depth from a depth file mapped as `dvs render --depth` maps it.
#pragma once
#include <cstdint>
#include <vector>

#include "dvs/views.hpp"
#include "npy_arrays.hpp"
#include "preview_options.hpp"

namespace preview {

struct Inputs {
  std::vector<uint8_t> frame_rgb;   // u8 [H,W,3] (a video's frame or a u8 frame array)
  NpyArray frame_npy;               // or an f32 [3,H,W] frame array
  std::vector<float> depth;         // f32 [H,W]
  bool depth_is_disparity = false;  // a one-frame [H,W] disparity .npy: the scene converts it (as dvs render does)
  dvs::HostView frame_view, depth_view;
  std::vector<uint8_t> frame_rgba;  // the input panel
  int source_height = 0, source_width = 0;  // the video file's frame (0: the frame array is at the working size)
};

// Throws std::runtime_error / dvs::Error naming the file and what is wrong.
Inputs read_inputs(const PreviewOptions& o);

}  // namespace preview
