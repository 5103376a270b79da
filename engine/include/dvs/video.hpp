// dvs's video component (libdvs_video; CMake: find_package(dvs COMPONENTS video) → dvs::video; pkg-config:
// dvs-video): reading and writing video files (.mp4 and what FFmpeg reads) and depth images (.png, .exr) through
// OpenCV. The core library (dvs::core) reads and writes only .npy frame arrays; without this component any other
// file is refused with a dvs::Error that says to link it.
#pragma once
#include "dvs/api.hpp"

namespace dvs {

// Makes the video component the core library's reader and writer of video files and depth images. Call it once,
// before the first file is read: it is what keeps the linker from dropping libdvs_video (an application that
// never calls into a library may lose it under --as-needed). Loading the library registers it too; calling again
// does nothing. Defined in libdvs_video, not in libdvs.
DVS_API void enable_video_files();

}  // namespace dvs
