#include "preview_inputs.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

#include "dvs/depth_file.hpp"
#include "dvs/error.hpp"
#ifdef DVS_PREVIEW_VIDEO
#include "dvs/video.hpp"
#endif

namespace preview {

namespace {

std::string shape_text(const std::vector<int64_t>& s) {
  std::string got;
  for (int64_t d : s) got += (got.empty() ? "" : "x") + std::to_string(d);
  return got;
}

// The frame of frame_index from an .npy frame array (u8 [H,W,3] or f32 [3,H,W], optionally with a frame axis).
void read_frame_npy(const PreviewOptions& o, Inputs& in) {
  const int64_t H = o.height, W = o.width;
  in.frame_npy = read_npy(o.frame_npy);
  auto& s = in.frame_npy.shape;
  const bool u8 = in.frame_npy.dtype == "u1";
  if (s.size() == 4) {  // a frame axis first
    if (o.frame_index >= s[0])
      throw std::runtime_error(o.frame_npy + ": --frame-index " + std::to_string(o.frame_index) + " but it holds " +
                               std::to_string(s[0]) + " frames");
    auto& bytes = in.frame_npy.bytes;
    const size_t plane = bytes.size() / size_t(s[0]);
    bytes.erase(bytes.begin(), bytes.begin() + std::ptrdiff_t(plane * size_t(o.frame_index)));
    bytes.resize(plane);
    s.erase(s.begin());
  }
  const std::vector<int64_t> want = u8 ? std::vector<int64_t>{H, W, 3} : std::vector<int64_t>{3, H, W};
  if (s != want)
    throw std::runtime_error(o.frame_npy + ": shape " + shape_text(s) + " is not a frame of --size " +
                             std::to_string(H) + "x" + std::to_string(W) +
                             " (u8 [H,W,3] or f32 [3,H,W], optionally with a frame axis first)");
  if (u8) {
    in.frame_rgb = std::move(in.frame_npy.bytes);
    in.frame_npy = {};
  }
}

void read_frame_video(const PreviewOptions& o, Inputs& in) {
#ifdef DVS_PREVIEW_VIDEO
  dvs::enable_video_files();
  dvs::VideoFrames v;
  try {
    v = dvs::read_video_frames(o.video, o.frame_index, 1, o.height, o.width, o.squash);
  } catch (const dvs::Error& e) {  // the frame the user asked for, named as they asked for it
    throw std::runtime_error("--video " + o.video + " --frame-index " + std::to_string(o.frame_index) + ": " + e.what());
  }
  in.frame_rgb = std::move(v.rgb);
  in.source_height = v.source_height;
  in.source_width = v.source_width;
#else
  (void)in;
  throw std::runtime_error("--video " + o.video + ": this dvs-preview was built against a dvs without its video "
                           "component (find_package(dvs COMPONENTS video) found none): rebuild dvs with "
                           "-DDVS_VIDEO_IO=ON, or give the frame as --frame-npy");
#endif
}

// The input panel: the frame as RGBA8.
void make_panel(const PreviewOptions& o, Inputs& in) {
  const size_t n = size_t(o.height) * size_t(o.width);
  in.frame_rgba.resize(n * 4);
  for (size_t i = 0; i < n; ++i) {
    for (size_t c = 0; c < 3; ++c) {
      if (!in.frame_rgb.empty()) {
        in.frame_rgba[i * 4 + c] = in.frame_rgb[i * 3 + c];
      } else {
        float f;
        std::memcpy(&f, &in.frame_npy.bytes[(c * n + i) * 4], 4);
        in.frame_rgba[i * 4 + c] = uint8_t(std::lround(std::clamp((f + 1.0f) * 127.5f, 0.0f, 255.0f)));
      }
    }
    in.frame_rgba[i * 4 + 3] = 255;
  }
}

// A one-frame [H,W] .npy at the working size: the scene converts its disparity itself (one frame is its own clip).
bool read_single_depth_npy(const PreviewOptions& o, Inputs& in) {
  if (o.depth.size() < 4 || o.depth.substr(o.depth.size() - 4) != ".npy") return false;
  NpyArray d = read_npy(o.depth);
  if (d.shape.size() != 2) return false;
  if (d.dtype != "f4") throw std::runtime_error(o.depth + ": depth must be float32, not " + d.dtype);
  if (d.shape != std::vector<int64_t>{o.height, o.width})
    throw std::runtime_error(o.depth + ": one frame of depth " + shape_text(d.shape) + " is not at --size " +
                             std::to_string(o.height) + "x" + std::to_string(o.width) + " (give [F,H,W] to have it mapped)");
  in.depth.resize(d.bytes.size() / 4);
  std::memcpy(in.depth.data(), d.bytes.data(), d.bytes.size());
  in.depth_is_disparity = !o.metric_depth;
  return true;
}

}  // namespace

Inputs read_inputs(const PreviewOptions& o) {
  Inputs in;
  const int64_t H = o.height, W = o.width;
  if (!o.video.empty()) read_frame_video(o, in);
  else read_frame_npy(o, in);
  in.frame_view = in.frame_rgb.empty()
                      ? dvs::HostView{in.frame_npy.bytes.data(), dvs::ElementType::f32, {3, H, W}}
                      : dvs::HostView{in.frame_rgb.data(), dvs::ElementType::u8, {H, W, 3}};
  make_panel(o, in);

  if (!o.depth_model.empty()) return in;  // estimated once dvs's context exists (model_depth.hpp)
  if (!read_single_depth_npy(o, in)) {  // the clip's depth file, converted and mapped exactly as dvs render does
    dvs::DepthFileOptions d;
    d.metric_depth = o.metric_depth;
    d.source_height = in.source_height;
    d.source_width = in.source_width;
    d.squash = o.squash;
    d.depth_fit = o.depth_fit;
    in.depth = dvs::load_depth_frame(o.depth, o.frame_index, o.height, o.width, d).depth;
    in.depth_is_disparity = false;  // converted over the whole clip to metric depth
  }
  in.depth_view = {in.depth.data(), dvs::ElementType::f32, {H, W}};
  return in;
}

}  // namespace preview
