// dvs::load_depth_frame (dvs/depth_file.hpp), from a file or from a clip in memory: dvs render's depth path (io/depth.hpp load_depth, then
// map_depth_to_video) for one frame. The disparity conversion needs the whole clip (it normalises over it), the
// mapping onto the working frame is per frame, so the clip is converted and only frame k is mapped.
#include <algorithm>
#include <cstring>

#include "dvs/depth_file.hpp"
#include "dvs/error.hpp"
#include "io/depth.hpp"

namespace dvs {

namespace {

void check_size(const std::string& name, int height, int width) {
  if (height <= 0 || width <= 0)
    throw Error(name + ": load_depth_frame takes a working size > 0, got " + std::to_string(height) + "x" +
                std::to_string(width), ErrorKind::invalid_argument);
}

DepthOptions conversion(const DepthFileOptions& options) {
  DepthOptions d;
  d.values = options.metric_depth ? DepthValues::depth : DepthValues::disparity;
  return d;
}

// Both forms: frame k of the converted clip (f32 [N,h,w] metric depth) mapped onto the working frame.
DepthFrame frame_of_clip(const HostTensor& clip, const std::string& name, int frame_index, int height, int width,
                         const DepthFileOptions& options) {
  const int frames = int(clip.shape[0]), h = int(clip.shape[1]), w = int(clip.shape[2]);
  if (frame_index < 0 || frame_index >= frames)
    throw Error(name + ": frame " + std::to_string(frame_index) + " asked for, but it holds " +
                std::to_string(frames) + " frame(s) of depth (0.." + std::to_string(frames - 1) + ")",
                ErrorKind::invalid_argument);
  HostTensor one({1, h, w}, DType::f32);
  std::memcpy(one.as<float>(), clip.as<float>() + size_t(frame_index) * size_t(h) * size_t(w), one.bytes());

  VideoFrameGeometry video;
  video.source_height = options.source_height > 0 ? options.source_height : height;
  video.source_width = options.source_width > 0 ? options.source_width : width;
  video.height = height;
  video.width = width;
  video.resize = options.squash ? ResizeMode::squash : ResizeMode::crop;
  const HostTensor mapped = map_depth_to_video(one, 1, video, parse_depth_fit(options.depth_fit), false, name);

  DepthFrame out;
  out.height = height;
  out.width = width;
  out.frames_in_file = frames;
  out.depth.assign(mapped.as<float>(), mapped.as<float>() + size_t(height) * size_t(width));
  return out;
}

}  // namespace

DepthFrame load_depth_frame(const std::filesystem::path& path, int frame_index, int height, int width,
                            const DepthFileOptions& options) {
  const std::string name = path.string();
  check_size(name, height, width);
  if (!depth_source_exists(path)) throw Error(name + ": no such depth file");
  parse_depth_fit(options.depth_fit);  // a wrong mode is named before the file is read
  return frame_of_clip(load_depth(path, conversion(options)), name, frame_index, height, width, options);
}

DepthFrame load_depth_frame(const ConstHostView& clip, int frame_index, int height, int width,
                            const DepthFileOptions& options) {
  const std::string name = "depth in memory";
  check_size(name, height, width);
  if (clip.data == nullptr || clip.type != ElementType::f32 || clip.shape.size() != 3 || clip.elements() <= 0)
    throw Error(name + ": load_depth_frame takes the clip's depth as f32 [F,H,W] (what DepthEstimator writes), got " +
                clip.describe(), ErrorKind::invalid_argument);
  parse_depth_fit(options.depth_fit);
  HostTensor values({clip.shape[0], clip.shape[1], clip.shape[2]}, DType::f32);
  std::memcpy(values.as<float>(), clip.data, values.bytes());
  // depth_from_array is the conversion load_depth applies to a file's array (the same validation, the same values).
  return frame_of_clip(depth_from_array(values, name, conversion(options)), name, frame_index, height, width, options);
}

}  // namespace dvs
