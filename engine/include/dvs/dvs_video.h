/* The C API of dvs's video component (libdvs_video; pkg-config dvs-video; CMake dvs::video): video files (.mp4 and
 * what FFmpeg reads) and depth images (.png, .exr) for every C call that takes a file path (dvs_job_start_render,
 * dvs_job_start_pipeline, dvs_preflight_*, ...). Without it the core library reads only .npy frame arrays and
 * refuses other files with a message that says to link this component. C99; see dvs/dvs.h for the conventions.
 *
 * A C program:      cc app.c $(pkg-config --cflags --libs dvs-video)   and call dvs_enable_video_files() once.
 * Python (ctypes):  load libdvs.so, then libdvs_video.so from the same folder, and call its
 *                   dvs_enable_video_files() (docs/c-api.md shows it). */
#ifndef DVS_VIDEO_H
#define DVS_VIDEO_H

#include "dvs/dvs.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Makes the video component the core's reader and writer of video files and depth images (dvs::enable_video_files).
 * Call it once before the first file is read: the call is what keeps a linker with --as-needed (Debian's gcc passes
 * it by default) from dropping libdvs_video from a program that otherwise never calls into it. Loading the library
 * registers it too; calling again does nothing. Always DVS_OK. Defined in libdvs_video. */
DVS_API dvs_status dvs_enable_video_files(void);

#ifdef __cplusplus
}
#endif

#endif /* DVS_VIDEO_H */
