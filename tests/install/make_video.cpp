// Writes a small test video with OpenCV (the install test's input for the video consumers): argv[1], 5 frames of
// 64x48 (W x H), MPEG-4 part 2 in .mp4 (every FFmpeg build encodes it).
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

#include <cstdio>

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  cv::VideoWriter writer(argv[1], cv::CAP_FFMPEG, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), 10, cv::Size(64, 48));
  if (!writer.isOpened()) {
    std::fprintf(stderr, "make_video: cannot write %s\n", argv[1]);
    return 1;
  }
  for (int f = 0; f < 5; ++f) writer.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(40 * f, 100, 200 - 30 * f)));
  return 0;
}
