// dvs::read_video_frames (dvs/video.hpp): the video component's public reader of frames into host memory. It calls
// the same OpenCV reader the core's read_video forwards to (so the frames are dvs render's, level for level) and
// hands back 8-bit RGB, the layout applications and the embedding API take.
#include <string>

#include "dvs/error.hpp"
#include "dvs/video.hpp"
#include "io/pixel_levels.hpp"
#include "video/opencv_video.hpp"

namespace dvs {
namespace {

// What both readers report besides the pixels: which frames, their size, and the file's.
VideoFrames frames_described(int first, int count, int height, int width, const VideoInfo& info) {
  VideoFrames out;
  out.first = first;
  out.count = count;
  out.height = height;
  out.width = width;
  out.source_height = info.height;
  out.source_width = info.width;
  out.frames_in_file = info.frames_in_file;
  out.fps = info.fps;
  return out;
}

// A call that asks for frames past the video's end: what was asked (the call's own arguments) and what there is.
[[noreturn]] void throw_frames_past_end(const std::string& name, int first, int count, int have) {
  const std::string asked = count == 1 ? "frame " + std::to_string(first)
                                       : "frames " + std::to_string(first) + ".." + std::to_string(first + count - 1);
  throw Error(name + ": " + asked + " asked for, but the video holds " + std::to_string(have) + " frame" +
              (have == 1 ? "" : "s") + " (" + (have == 1 ? "frame 0" : "frames 0.." + std::to_string(have - 1)) + ")");
}

}  // namespace

VideoFrames read_video_frames(const std::filesystem::path& path, int first, int count, int height, int width,
                              bool squash) {
  const std::string name = path.string();
  if (first < 0 || count < 1)
    throw Error(name + ": read_video_frames takes first ≥ 0 and count ≥ 1, got first " + std::to_string(first) +
                ", count " + std::to_string(count));
  if (height < 0 || width < 0 || (height == 0) != (width == 0))
    throw Error(name + ": read_video_frames takes a working size with both height and width > 0 (or both 0 for the "
                "file's size), got " + std::to_string(height) + "x" + std::to_string(width));
  VideoReadOptions o;
  o.max_frames = first + count;  // decoding is sequential; a frame decodes the same whatever follows it
  o.height = height;
  o.width = width;
  o.resize = squash ? ResizeMode::squash : ResizeMode::crop;
  o.fewer_frames_ok = true;  // named below in this call's terms, not as the dvs program's --frames
  VideoInfo info;
  const HostTensor planes = opencv_read_video(path, o, &info);  // [first+count,3,H,W] in [−1,1]
  if (planes.shape[0] < first + count) throw_frames_past_end(name, first, count, int(planes.shape[0]));

  VideoFrames out = frames_described(first, count, int(planes.shape[2]), int(planes.shape[3]), info);
  const size_t plane = size_t(out.height) * size_t(out.width);
  out.rgb.resize(size_t(count) * plane * 3);
  const float* src = planes.as<float>();
  for (size_t f = 0; f < size_t(count); ++f)
    for (size_t i = 0; i < plane; ++i)
      for (size_t c = 0; c < 3; ++c)  // the reader's levels back exactly: unit_to_level(level_to_unit(v)) = v
        out.rgb[(f * plane + i) * 3 + c] = unit_to_level(src[((size_t(first) + f) * 3 + c) * plane + i]);
  return out;
}

VideoFrames read_video_frames_for_depth(const std::filesystem::path& path, int count, int max_long_side) {
  const std::string name = path.string();
  if (count < 1 || max_long_side < 0)
    throw Error(name + ": read_video_frames_for_depth takes count ≥ 1 and max_long_side ≥ 0, got count " +
                std::to_string(count) + ", max_long_side " + std::to_string(max_long_side));
  VideoInfo info;
  // The depth estimate's own reader (pipeline/depth_estimate.cpp decodes with it), so the frames are its frames.
  const HostTensor rgb = opencv_read_video_rgb8(path, count, max_long_side, &info, true);
  if (rgb.shape[0] < count) throw_frames_past_end(name, 0, count, int(rgb.shape[0]));
  VideoFrames out = frames_described(0, count, int(rgb.shape[1]), int(rgb.shape[2]), info);
  const uint8_t* src = rgb.as<uint8_t>();
  out.rgb.assign(src, src + size_t(count) * size_t(out.height) * size_t(out.width) * 3);
  return out;
}

}  // namespace dvs
