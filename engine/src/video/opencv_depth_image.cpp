#include "video/opencv_depth_image.hpp"

#include <cstdlib>
#include <cstring>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "dvs/error.hpp"

namespace dvs {

HostTensor opencv_read_depth_image(const std::filesystem::path& file, const char* kind) {
  const std::string name = file.string();
  // OpenCV reads EXR only when this is set before the first EXR read (a security default).
  if (std::strcmp(kind, "EXR") == 0) setenv("OPENCV_IO_ENABLE_OPENEXR", "1", 0);
  cv::Mat img;
  try {
    img = cv::imread(name, cv::IMREAD_UNCHANGED | cv::IMREAD_ANYDEPTH);
  } catch (const cv::Exception& e) {
    throw Error(name + ": cannot read the " + kind + " depth image (" + e.what() + ")");
  }
  if (img.empty()) throw Error(name + ": not a readable " + kind + " image (corrupt or truncated?)");
  if (img.channels() != 1)
    throw Error(name + ": depth images must be single-channel (grayscale); this one has " +
                std::to_string(img.channels()) + " channels");
  cv::Mat f;
  img.convertTo(f, CV_32F);  // integers keep their stored values
  HostTensor out({int64_t(f.rows), int64_t(f.cols)}, DType::f32);
  for (int y = 0; y < f.rows; ++y) std::memcpy(out.as<float>() + size_t(y) * f.cols, f.ptr<float>(y), size_t(f.cols) * 4);
  return out;
}

}  // namespace dvs
