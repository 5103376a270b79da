// set_third_party_logs (dvs/logs.hpp): records the choice (quiet_stderr.cpp) and passes it on to the video
// component, which owns OpenCV's and FFmpeg's log levels. Kept apart from quiet_stderr.cpp so that the video
// component's library, which needs QuietStderr, does not take in the core's video registry with it.
#include "dvs/logs.hpp"
#include "io/third_party_logs.hpp"
#include "io/video_backend.hpp"

namespace dvs {

void set_third_party_logs(bool verbose) {
  remember_third_party_logs(verbose);
  // The component applies a choice made before it was loaded when it registers (video_backend.cpp).
  if (const VideoBackend* backend = video_backend()) backend->set_logs(verbose);
}

}  // namespace dvs
