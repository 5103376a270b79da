// The video component's table (io/video_backend.hpp) and its registration: when libdvs_video is loaded (or the
// programs and tests, which link these objects directly, start), a static initializer hands the table to the core;
// dvs::enable_video_files() does the same for applications that must reference the library to keep it linked.
#include <cstdlib>
#include <opencv2/core.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <string>

#include "dvs/video.hpp"
#include "io/third_party_logs.hpp"
#include "io/video_backend.hpp"
#include "video/opencv_depth_image.hpp"
#include "video/opencv_video.hpp"

namespace dvs {
namespace {

std::string opencv_version() { return "OpenCV " + cv::getVersionString(); }

void set_opencv_logs(bool verbose) {
  // In libdvs_video this component has its own copy of the log state (QuietStderr reads it); in the programs it is
  // the one the core set already.
  remember_third_party_logs(verbose);
  if (verbose) {
    cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_INFO);
    return;
  }
  // OpenCV's FFmpeg backend installs a filtering log callback at this level when the variable is set
  // (AV_LOG_QUIET = −8); without it FFmpeg's error lines reach stderr.
  setenv("OPENCV_FFMPEG_LOGLEVEL", "-8", 0);
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
}

const VideoBackend kOpenCvBackend{opencv_version,         set_opencv_logs,    opencv_read_video,
                                  opencv_read_video_rgb8, opencv_write_video, opencv_read_depth_image};

const bool kRegistered = [] {
  detail::set_video_backend(&kOpenCvBackend);
  return true;
}();

}  // namespace

void enable_video_files() { detail::set_video_backend(&kOpenCvBackend); }

}  // namespace dvs
