// Video files through OpenCV (FFmpeg backend): decode to f32 RGB frames [F,3,H,W] in [−1,1] at a working
// size, and encode such frames to .mp4. Writes go to a temporary name and are renamed when complete, so
// an interrupted run never leaves a file that looks finished.
#pragma once
#include <filesystem>
#include <string>
#include <vector>
#include <string>

#include "io/host_tensor.hpp"

namespace dvs {

enum class ResizeMode {
  crop,    // keep the aspect ratio, scale to cover the working size, cut the centre (default)
  squash,  // scale each axis independently (the official code's behaviour)
};

struct VideoReadOptions {
  int max_frames = 0;  // the first N frames (0 = all); a video with fewer is an error (too_few_frames, video.cpp)
  int height = 0, width = 0;  // 0 = keep the file's size
  ResizeMode resize = ResizeMode::crop;
  // A video of fewer than max_frames frames gives those it has (the caller names the shortfall); else it is the
  // error that suggests the dvs program's --frames.
  bool fewer_frames_ok = false;
};

struct VideoInfo {
  int width = 0, height = 0;  // of the file
  int frames = 0;             // decoded (after max_frames)
  int frames_in_file = 0;     // the container's frame count (0 when it does not say)
  double fps = 0;
  // What the reader noticed without failing (a header that announces more frames than decode): the core's
  // read_video logs them (io/library_log.hpp), since the video component has no handle on the application's log.
  std::vector<std::string> warnings;
};

// [F,3,H,W] f32 RGB in [−1,1]. Throws dvs::Error naming the file and the cause when it cannot be opened
// (empty, truncated, no video stream: video_probe.hpp), holds no frames, or fewer than max_frames (suggesting the
// --frames that works).
HostTensor read_video(const std::filesystem::path& path, const VideoReadOptions& options = {}, VideoInfo* info = nullptr);

// The decoded frames as they are, u8 RGB [F,H,W,3] (what Video-Depth-Anything takes). max_frames as above;
// when the long side exceeds max_long_side (> 0), frames are scaled to fit it as VDA's run.py does (--max_res).
HostTensor read_video_rgb8(const std::filesystem::path& path, int max_frames = 0, int max_long_side = 0,
                           VideoInfo* info = nullptr);

// Frames [F,3,H,W] (RGB) or [F,1,H,W] / [F,H,W] (gray, written as RGB) in [−1,1] (values are clamped).
// H.264 when the FFmpeg build has an encoder for it, else MPEG-4 part 2. The same frames always give the
// same bytes (the encoder's uninitialised reads see a fixed fill, video.cpp).
void write_video(const std::filesystem::path& path, const HostTensor& frames, double fps);

// The version of the OpenCV library that reads and writes videos (for run records).
std::string video_library_version();

// Side by side: each input [F,3,H,W] with the same F and H (widths may differ).
HostTensor hstack_videos(const std::vector<const HostTensor*>& videos);

}  // namespace dvs
