// dvs::load_depth_frame (dvs/depth_file.hpp): dvs render's depth path (io/depth.hpp load_depth, then
// map_depth_to_video) for one frame. The disparity conversion needs the whole clip (it normalises over it), the
// mapping onto the working frame is per frame, so the clip is converted and only frame k is mapped.
#include <algorithm>
#include <cstring>

#include "dvs/depth_file.hpp"
#include "dvs/error.hpp"
#include "io/depth.hpp"

namespace dvs {

DepthFrame load_depth_frame(const std::filesystem::path& path, int frame_index, int height, int width,
                            const DepthFileOptions& options) {
  const std::string name = path.string();
  if (height <= 0 || width <= 0)
    throw Error(name + ": load_depth_frame takes a working size > 0, got " + std::to_string(height) + "x" +
                std::to_string(width));
  if (!depth_source_exists(path)) throw Error(name + ": no such depth file");
  const DepthFit fit = parse_depth_fit(options.depth_fit);
  DepthOptions d;
  d.values = options.metric_depth ? DepthValues::depth : DepthValues::disparity;
  const HostTensor clip = load_depth(path, d);  // f32 [N,h,w] metric depth
  const int frames = int(clip.shape[0]), h = int(clip.shape[1]), w = int(clip.shape[2]);
  if (frame_index < 0 || frame_index >= frames)
    throw Error(name + ": frame " + std::to_string(frame_index) + " asked for, but the file holds " +
                std::to_string(frames) + " frame(s) of depth (0.." + std::to_string(frames - 1) + ")");
  HostTensor one({1, h, w}, DType::f32);
  std::memcpy(one.as<float>(), clip.as<float>() + size_t(frame_index) * size_t(h) * size_t(w), one.bytes());

  VideoFrameGeometry video;
  video.source_height = options.source_height > 0 ? options.source_height : height;
  video.source_width = options.source_width > 0 ? options.source_width : width;
  video.height = height;
  video.width = width;
  video.resize = options.squash ? ResizeMode::squash : ResizeMode::crop;
  const HostTensor mapped = map_depth_to_video(one, 1, video, fit, false, name);

  DepthFrame out;
  out.height = height;
  out.width = width;
  out.frames_in_file = frames;
  out.depth.assign(mapped.as<float>(), mapped.as<float>() + size_t(height) * size_t(width));
  return out;
}

}  // namespace dvs
