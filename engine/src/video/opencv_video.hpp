// Video files through OpenCV's FFmpeg backend (the video component): what io/video.hpp's read_video,
// read_video_rgb8 and write_video do for a file that is not an .npy frame array, with the same contracts.
#pragma once
#include <filesystem>

#include "io/host_tensor.hpp"
#include "io/video.hpp"

namespace dvs {

HostTensor opencv_read_video(const std::filesystem::path& path, const VideoReadOptions& options, VideoInfo* info);
HostTensor opencv_read_video_rgb8(const std::filesystem::path& path, int max_frames, int max_long_side, VideoInfo* info);
// As above, but a video of fewer than max_frames frames gives the frames it has when fewer_frames_ok (the library's
// readers, dvs/video.hpp, name the shortfall in their own terms instead of the dvs program's --frames).
HostTensor opencv_read_video_rgb8(const std::filesystem::path& path, int max_frames, int max_long_side, VideoInfo* info,
                                  bool fewer_frames_ok);
void opencv_write_video(const std::filesystem::path& path, const HostTensor& frames, double fps);

}  // namespace dvs
