#include "models/vda/vda_preprocess.hpp"

#ifndef DVS_VIDEO_IO
#define DVS_VIDEO_IO 1  // CMake defines it as 0 for this file in a DVS_VIDEO_IO=OFF build
#endif

#include <algorithm>
#include <cmath>
#if DVS_VIDEO_IO
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#endif
#include <string>

#include "dvs/error.hpp"

namespace dvs {
namespace {

// Transform.Resize.constrain_to_multiple_of with min_val: numpy round (half to even) to a multiple, the ceiling
// multiple when that falls below min_val.
int64_t constrain_to_multiple_of(double x, int multiple, double min_val) {
  double y = std::nearbyint(x / multiple) * multiple;  // FE_TONEAREST: half to even, as np.round
  if (y < min_val) y = std::ceil(x / multiple) * multiple;
  return int64_t(y);
}

}  // namespace

VdaInputSize vda_input_size(int64_t frame_h, int64_t frame_w, int input_size, int multiple) {
  if (frame_h < 1 || frame_w < 1 || input_size < 1 || multiple < 1)
    throw Error("depth: cannot size a " + std::to_string(frame_w) + "x" + std::to_string(frame_h) +
                " frame for input size " + std::to_string(input_size));
  const double ratio = double(std::max(frame_h, frame_w)) / double(std::min(frame_h, frame_w));
  double size = input_size;
  if (ratio > 1.78) {  // VDA shrinks the input size of clips wider than 16:9 (memory)
    const double shrunk = std::trunc(input_size * 1.777 / ratio);          // Python int()
    size = std::nearbyint(shrunk / multiple) * multiple;                   // Python round(): half to even
  }
  // Resize(lower_bound, keep_aspect_ratio): the side that needs the larger scale is fitted.
  const double scale = std::max(size / double(frame_h), size / double(frame_w));
  VdaInputSize s{constrain_to_multiple_of(scale * double(frame_h), multiple, size),
                 constrain_to_multiple_of(scale * double(frame_w), multiple, size)};
  if (s.height < multiple || s.width < multiple)
    throw Error("depth: input size " + std::to_string(input_size) + " gives a " + std::to_string(s.width) + "x" +
                std::to_string(s.height) + " network input for a " + std::to_string(frame_w) + "x" +
                std::to_string(frame_h) + " clip; use a larger --input-size");
  return s;
}

void vda_preprocess_frame(const uint8_t* rgb, int64_t frame_h, int64_t frame_w, VdaInputSize size, const VdaConfig& cfg,
                          float* out) {
#if !DVS_VIDEO_IO
  throw Error("depth: Video-Depth-Anything's preprocessing (OpenCV's cubic resize) is missing: built without video "
              "I/O (DVS_VIDEO_IO=OFF)");
#else
  // frame.astype(float32) / 255.0 (a float32 division), then cv2.resize INTER_CUBIC on the float32 HxWx3 image.
  const cv::Mat u8(int(frame_h), int(frame_w), CV_8UC3, const_cast<uint8_t*>(rgb));
  cv::Mat f32(int(frame_h), int(frame_w), CV_32FC3);
  const size_t n = size_t(frame_h) * size_t(frame_w) * 3;
  float* fp = f32.ptr<float>();
  for (size_t i = 0; i < n; ++i) fp[i] = float(rgb[i]) / 255.0f;
  cv::Mat resized;
  cv::resize(f32, resized, cv::Size(int(size.width), int(size.height)), 0, 0, cv::INTER_CUBIC);
  // (x - mean) / std with numpy float64 constants, stored float32; HWC -> CHW.
  const size_t plane = size_t(size.height) * size_t(size.width);
  for (int64_t y = 0; y < size.height; ++y) {
    const float* row = resized.ptr<float>(int(y));
    for (int64_t x = 0; x < size.width; ++x)
      for (int c = 0; c < 3; ++c) {
        const double mean = cfg.mean[size_t(c)], sd = cfg.std[size_t(c)];
        out[size_t(c) * plane + size_t(y) * size.width + size_t(x)] = float((double(row[3 * x + c]) - mean) / sd);
      }
  }
#endif
}

}  // namespace dvs
