// dvs/dvs_video.h: the video component's one C call, dvs::enable_video_files behind a C name (exported from
// libdvs_video by cmake/dvs_video_exports.map).
#include "dvs/dvs_video.h"

#include "dvs/video.hpp"

extern "C" dvs_status dvs_enable_video_files(void) {
  dvs::enable_video_files();  // registers a static table: nothing in it can throw
  return DVS_OK;
}
