// One frame of a depth file (what `dvs depth` and Video-Depth-Anything write for a whole clip) as a
// PointCloudScene takes it: converted and mapped onto the working frame exactly as `dvs render --depth` does, so
// a scene built from frame k renders what `dvs render` renders for frame k at the same pose.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "dvs/api.hpp"
#include "dvs/views.hpp"

namespace dvs {

struct DepthFileOptions {
  bool metric_depth = false;  // the file holds metric depth (dvs render --metric-depth), not disparity
  // The video frame the depth was estimated on (VideoFrames::source_height/width, dvs/video.hpp) and how that video
  // was brought to the working size (dvs render --resize squash); 0 × 0: the depth belongs to a frame of the working size.
  int source_height = 0, source_width = 0;
  bool squash = false;
  std::string depth_fit = "error";  // dvs render --depth-fit: error | stretch | crop (another aspect than the video)
};

struct DepthFrame {
  std::vector<float> depth;  // f32 [height, width] METRIC depth: give it to PointCloudScene with depth_is_disparity =
                             // false (disparity is converted over the whole clip, as dvs render does)
  int height = 0, width = 0;
  int frames_in_file = 0;    // the depth file's frame count
};

// Frame `frame_index` of the depth file `path` (.npy [N,H,W] or .npz, key "depths" or FILE.npz:KEY; as dvs render
// --depth reads them) at height × width. Throws dvs::Error naming the file (unreadable, wrong shape or values,
// frame_index ≥ its frame count, an aspect ratio the fit refuses).
DVS_API DepthFrame load_depth_frame(const std::filesystem::path& path, int frame_index, int height, int width,
                                    const DepthFileOptions& options = {});
// The same for a clip's depth in memory: `clip` f32 [F,h,w] as DepthEstimator gives it (disparity, or metric depth
// with options.metric_depth) for frames of VideoFrames from read_video_frames_for_depth (pass its source_height/
// width in options). Converted and mapped by the one implementation of the file form, so frame k equals what
// `dvs render --depth-model` renders for frame k. Errors name the clip as "depth in memory".
DVS_API DepthFrame load_depth_frame(const ConstHostView& clip, int frame_index, int height, int width,
                                    const DepthFileOptions& options = {});

}  // namespace dvs
