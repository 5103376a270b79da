// Writes the preview test's video (run_preview_test.sh) with OpenCV: raw u8 RGB frames [F,H,W,3] (make_scene.py's
// frames.rgb) as MPEG-4 part 2 in .mp4 (every FFmpeg build encodes it), 10 fps.
// usage: make_video FRAMES.rgb F H W OUT.mp4
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <vector>

int main(int argc, char** argv) {
  if (argc != 6) {
    std::fprintf(stderr, "usage: make_video FRAMES.rgb F H W OUT.mp4\n");
    return 2;
  }
  const int F = std::atoi(argv[2]), H = std::atoi(argv[3]), W = std::atoi(argv[4]);
  std::vector<unsigned char> rgb(size_t(F) * H * W * 3);
  std::ifstream in(argv[1], std::ios::binary);
  if (!in.read(reinterpret_cast<char*>(rgb.data()), std::streamsize(rgb.size()))) {
    std::fprintf(stderr, "make_video: %s does not hold %d frames of %dx%d RGB\n", argv[1], F, H, W);
    return 1;
  }
  cv::VideoWriter writer(argv[5], cv::CAP_FFMPEG, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), 10, cv::Size(W, H));
  if (!writer.isOpened()) {
    std::fprintf(stderr, "make_video: cannot write %s\n", argv[5]);
    return 1;
  }
  for (int f = 0; f < F; ++f) {
    cv::Mat frame(H, W, CV_8UC3, rgb.data() + size_t(f) * H * W * 3), bgr;
    cv::cvtColor(frame, bgr, cv::COLOR_RGB2BGR);
    writer.write(bgr);
  }
  return 0;
}
