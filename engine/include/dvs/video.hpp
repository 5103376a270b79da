// dvs's video component (libdvs_video; CMake: find_package(dvs COMPONENTS video) → dvs::video; pkg-config:
// dvs-video): reading and writing video files (.mp4 and what FFmpeg reads) and depth images (.png, .exr) through
// OpenCV. The core library (dvs::core) reads and writes only .npy frame arrays; without this component any other
// file is refused with a dvs::Error that says to link it.
#pragma once
#include <cstdint>
#include <filesystem>
#include <vector>

#include "dvs/api.hpp"

namespace dvs {

// Makes the video component the core library's reader and writer of video files and depth images. Call it once,
// before the first file is read: it is what keeps the linker from dropping libdvs_video (an application that
// never calls into a library may lose it under --as-needed). Loading the library registers it too; calling again
// does nothing. Defined in libdvs_video, not in libdvs.
DVS_API void enable_video_files();

// Frames of a video file decoded into host memory at a working size.
struct VideoFrames {
  std::vector<uint8_t> rgb;          // u8 [count, height, width, 3] RGB: what PointCloudScene and DepthEstimator take
  int first = 0, count = 0;          // which frames of the file these are
  int height = 0, width = 0;         // the working size
  int source_height = 0, source_width = 0;  // the file's frame size (depth files are mapped from it: dvs/depth_file.hpp)
  int frames_in_file = 0;            // the container's frame count (0 when it does not say)
  double fps = 0;
  // One frame's pixels (u8 [height, width, 3]), frame `first + i` of the file.
  const uint8_t* frame(int i) const { return rgb.data() + size_t(i) * size_t(height) * size_t(width) * 3; }
};

// Decodes frames first .. first+count−1 of `path` brought to height × width exactly as `dvs render --size HxW`
// brings them (the same decoder; squash = `--resize squash`, else the centre is cropped to the working aspect and scaled).
// height = width = 0 keeps the file's size. Throws dvs::Error naming the file (cannot be opened, fewer frames than
// first + count, count < 1). Defined in libdvs_video.
DVS_API VideoFrames read_video_frames(const std::filesystem::path& path, int first, int count, int height, int width,
                                      bool squash = false);
// The first `count` frames of `path` as `dvs render --depth-model` and `dvs depth` feed them to the depth network
// (DepthEstimator, dvs/depth_frames.hpp): at the file's size, scaled down (both sides, bilinear) when its long side
// exceeds max_long_side (their --max-res; 0: no limit). The depth it gives maps onto the working frame with
// load_depth_frame (dvs/depth_file.hpp) and source_height/width. Throws dvs::Error naming the file (cannot be
// opened, fewer than `count` frames, count < 1). Defined in libdvs_video.
DVS_API VideoFrames read_video_frames_for_depth(const std::filesystem::path& path, int count, int max_long_side = 1280);

}  // namespace dvs
