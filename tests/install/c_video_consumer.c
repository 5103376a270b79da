/* A C99 program on a video file through the installed package (issue 34): dvs_preflight_render opens and decodes the
 * video argv[1] and notes "<frames> frames of <H>x<W>", which must hold argv[2]. tests/install/run_install_test.sh
 * builds it twice with `cc -std=c99 $(pkg-config --cflags --libs dvs-video) -Wl,--as-needed` (Debian's gcc passes
 * --as-needed by default): with CALLS_ENABLE=1 it calls dvs_enable_video_files() and reads the video; with
 * CALLS_ENABLE=0 nothing of libdvs_video is called, the linker drops it, and the report must name the missing video
 * component — which is why the call exists. Exit status 0 = as expected. */
#include <stdio.h>
#include <string.h>

#include "dvs/dvs.h"
#if CALLS_ENABLE
#include "dvs/dvs_video.h"
#endif

int main(int argc, char** argv) {
  dvs_render_options options;
  int32_t problems = 0;
  char report[8192];
  if (argc != 4) {
    fprintf(stderr, "usage: %s VIDEO EXPECTED_TEXT OUT_DIR\n", argv[0]);
    return 2;
  }
#if CALLS_ENABLE
  if (dvs_enable_video_files() != DVS_OK) return 1;
#endif
  if (dvs_render_options_default(&options) != DVS_OK) return 1;
  options.video = argv[1];
  options.depth = argv[1]; /* any existing file: only the video's checks matter here */
  options.out_dir = argv[3];
  options.frames = 0;
  if (dvs_preflight_render(&options, &problems, report, sizeof report, NULL) != DVS_OK) {
    fprintf(stderr, "%s: dvs_preflight_render: %s\n", argv[0], dvs_last_error());
    return 1;
  }
  printf("%s", report);
  if (strstr(report, argv[2]) == NULL) {
    fprintf(stderr, "%s: expected '%s' in the report\n", argv[0], argv[2]);
    return 1;
  }
  return 0;
}
