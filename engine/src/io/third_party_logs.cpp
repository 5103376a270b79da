#include "io/third_party_logs.hpp"

#ifndef DVS_VIDEO_IO
#define DVS_VIDEO_IO 1  // CMake defines it as 0 for this file in a DVS_VIDEO_IO=OFF build
#endif

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#if DVS_VIDEO_IO
#include <opencv2/core/utils/logger.hpp>
#endif

namespace dvs {
namespace {

bool g_verbose = false;

}  // namespace

void set_third_party_logs(bool verbose) {
  g_verbose = verbose;
#if DVS_VIDEO_IO
  if (verbose) {
    cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_INFO);
    return;
  }
  // OpenCV's FFmpeg backend installs a filtering log callback at this level when the variable is set
  // (AV_LOG_QUIET = −8); without it FFmpeg's error lines reach stderr.
  setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0);
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
#endif
}

bool third_party_logs_verbose() { return g_verbose; }

QuietStderr::QuietStderr() {
  if (g_verbose) return;
  std::fflush(stderr);
  const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (null < 0) return;
  saved_ = ::dup(2);
  if (saved_ >= 0) ::dup2(null, 2);
  ::close(null);
}

QuietStderr::~QuietStderr() {
  if (saved_ < 0) return;
  std::fflush(stderr);
  ::dup2(saved_, 2);
  ::close(saved_);
}

}  // namespace dvs
