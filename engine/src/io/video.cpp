#include "io/video.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>

#include "dvs/error.hpp"
#include "io/library_log.hpp"
#include "io/npy.hpp"
#include "io/pixel_levels.hpp"
#include "io/video_backend.hpp"
#include "io/video_probe.hpp"

namespace dvs {

// Frame arrays: every build reads a "video" that is an .npy file (recognised by its contents, whatever its name)
// of f32 [F,3,H,W] in [-1,1] or u8 [F,H,W,3] RGB, at its own size (no resizing): frames in as arrays, for the
// GPU bundle's end-to-end run. Without the video component (video_backend.hpp; none in a DVS_VIDEO_IO=OFF build)
// write_video stores the frames that way too, under the name it is given (output.mp4 then holds an .npy), and other
// files are refused.
namespace {

[[noreturn]] void no_video_io(const std::filesystem::path& path, const std::string& what) {
  if (!video_backend()) needs_video_component(path, what);
  throw Error(path.string() + ": " + what + " (frame arrays are read at their own size)");
}

bool is_npy(const std::filesystem::path& path) {
  char magic[6] = {};
  std::ifstream(path, std::ios::binary).read(magic, 6);
  return std::memcmp(magic, "\x93NUMPY", 6) == 0;
}

// Frames [F,3,H,W] f32 in [-1,1] from an .npy of that layout or of u8 [F,H,W,3] RGB; max_frames 0 = all.
HostTensor read_frames_npy(const std::filesystem::path& path, int max_frames, VideoInfo& vi) {
  if (!std::filesystem::is_regular_file(path)) throw Error(path.string() + ": no such video file");
  const HostTensor t = read_npy(path);
  const Shape& s = t.shape;
  const bool planar = s.size() == 4 && s[1] == 3 && t.dtype == DType::f32;
  const bool rgb8 = s.size() == 4 && s[3] == 3 && t.dtype == DType::u8;
  if (!planar && !rgb8)
    throw Error(path.string() + ": frame arrays must be f32 [F,3,H,W] in [-1,1] or u8 [F,H,W,3], got [" + shape_str(s) + "]");
  const int64_t F = max_frames > 0 ? std::min<int64_t>(s[0], max_frames) : s[0];
  const int64_t H = planar ? s[2] : s[1], W = planar ? s[3] : s[2];
  if (F == 0) throw Error(path.string() + ": the frame array holds no frames (its shape is [" + shape_str(s) + "])");
  if (max_frames > 0 && F < max_frames) throw_too_few_frames(path.string(), int(F), max_frames, 0);
  HostTensor out({F, 3, H, W}, DType::f32);
  const size_t plane = size_t(H * W);
  for (int64_t f = 0; f < F; ++f)
    for (int c = 0; c < 3; ++c)
      for (size_t i = 0; i < plane; ++i)
        out.as<float>()[(size_t(f) * 3 + c) * plane + i] =
            planar ? t.as<float>()[(size_t(f) * 3 + c) * plane + i] : level_to_unit(t.as<uint8_t>()[(size_t(f) * plane + i) * 3 + c]);
  vi = VideoInfo{int(W), int(H), int(F), int(s[0]), 30.0};
  return out;
}

// read_video of a frame array. A different working size is taken by nearest-neighbour sampling (no filtering:
// enough for preflight's probe and for arrays made at another size; give arrays at the working size for real runs)
// after the crop rule's centre cut.
HostTensor read_video_npy(const std::filesystem::path& path, const VideoReadOptions& o, VideoInfo* info) {
  VideoInfo vi;
  HostTensor in = read_frames_npy(path, o.max_frames, vi);
  if (info) *info = vi;
  const int w = o.width > 0 ? o.width : vi.width, h = o.height > 0 ? o.height : vi.height;
  if (w == vi.width && h == vi.height) return in;
  double x0 = 0, y0 = 0, sw = vi.width, sh = vi.height;  // the source window
  if (o.resize == ResizeMode::crop) {
    const double s = std::max(double(w) / vi.width, double(h) / vi.height);
    sw = std::min<double>(vi.width, w / s), sh = std::min<double>(vi.height, h / s);
    x0 = (vi.width - sw) / 2, y0 = (vi.height - sh) / 2;
  }
  const int64_t F = in.shape[0];
  HostTensor out({F, 3, h, w}, DType::f32);
  for (int64_t fc = 0; fc < F * 3; ++fc)
    for (int y = 0; y < h; ++y) {
      const int sy = std::min(vi.height - 1, int(y0 + (y + 0.5) * sh / h));
      for (int x = 0; x < w; ++x) {
        const int sx = std::min(vi.width - 1, int(x0 + (x + 0.5) * sw / w));
        out.as<float>()[(fc * h + y) * w + x] = in.as<float>()[(fc * vi.height + sy) * vi.width + sx];
      }
    }
  return out;
}

// read_video_rgb8 of a frame array.
HostTensor read_video_rgb8_npy(const std::filesystem::path& path, int max_frames, int max_long_side, VideoInfo* info) {
  VideoInfo vi;
  const HostTensor f = read_frames_npy(path, max_frames, vi);
  if (max_long_side > 0 && std::max(vi.width, vi.height) > max_long_side) no_video_io(path, "cannot scale the frames down");
  if (info) *info = vi;
  const int64_t F = f.shape[0], H = f.shape[2], W = f.shape[3];
  HostTensor out({F, H, W, 3}, DType::u8);
  for (int64_t n = 0; n < F; ++n)
    for (int64_t i = 0; i < H * W; ++i)
      for (int c = 0; c < 3; ++c)
        out.as<uint8_t>()[(n * H * W + i) * 3 + c] =
            unit_to_level(f.as<float>()[(n * 3 + c) * H * W + i]);
  return out;
}

// The video component's read with what it noticed logged (info may be null).
template <class Read>
HostTensor read_logged(VideoInfo* info, const Read& read) {
  VideoInfo local;
  VideoInfo& vi = info ? *info : local;
  HostTensor frames = read(&vi);
  for (const std::string& w : vi.warnings) log_warning(w);
  vi.warnings.clear();
  return frames;
}

}  // namespace

HostTensor read_video(const std::filesystem::path& path, const VideoReadOptions& o, VideoInfo* info) {
  if (std::filesystem::is_regular_file(path) && is_npy(path)) return read_video_npy(path, o, info);
  if (const VideoBackend* backend = video_backend()) return read_logged(info, [&](VideoInfo* vi) { return backend->read_video(path, o, vi); });
  if (std::filesystem::is_regular_file(path)) no_video_io(path, "decoding the video");
  return read_video_npy(path, o, info);  // names the missing file
}

HostTensor read_video_rgb8(const std::filesystem::path& path, int max_frames, int max_long_side, VideoInfo* info) {
  if (std::filesystem::is_regular_file(path) && is_npy(path)) return read_video_rgb8_npy(path, max_frames, max_long_side, info);
  if (const VideoBackend* backend = video_backend())
    return read_logged(info, [&](VideoInfo* vi) { return backend->read_video_rgb8(path, max_frames, max_long_side, vi); });
  if (std::filesystem::is_regular_file(path)) no_video_io(path, "decoding the video");
  return read_video_rgb8_npy(path, max_frames, max_long_side, info);  // names the missing file
}

void write_video(const std::filesystem::path& path, const HostTensor& frames, double fps) {
  if (const VideoBackend* backend = video_backend()) return backend->write_video(path, frames, fps);
  // Not silent: an application that links only dvs::core and asks for a job's .mp4 files gets frame arrays.
  log_warning(path.string() + ": written as an .npy frame array (f32 [F,3,H,W] in [-1,1]) under this name: this "
              "program has no video component (link dvs::video for .mp4 files)");
  const Shape& s = frames.shape;
  int64_t F = 0, C = 0, H = 0, W = 0;
  if (s.size() == 4 && (s[1] == 3 || s[1] == 1)) F = s[0], C = s[1], H = s[2], W = s[3];
  else if (s.size() == 3) F = s[0], C = 1, H = s[1], W = s[2];
  else throw Error("internal: write_video expects [F,3,H,W], [F,1,H,W] or [F,H,W], got [" + shape_str(s) + "]");
  if (F == 0) throw Error(path.string() + ": no frames to write");
  const std::vector<float> v = frames.to_f32();
  HostTensor out({F, 3, H, W}, DType::f32);
  const size_t plane = size_t(H * W);
  for (int64_t f = 0; f < F; ++f)
    for (int c = 0; c < 3; ++c)
      for (size_t i = 0; i < plane; ++i)
        out.as<float>()[(size_t(f) * 3 + c) * plane + i] =
            std::clamp(v[(size_t(f) * C + size_t(C == 3 ? c : 0)) * plane + i], -1.0f, 1.0f);
  write_npy(path, out);
}


HostTensor hstack_videos(const std::vector<const HostTensor*>& videos) {
  if (videos.empty()) throw Error("internal: hstack_videos of nothing");
  const int64_t F = videos[0]->shape[0], H = videos[0]->shape[2];
  int64_t W = 0;
  for (const HostTensor* v : videos) {
    if (v->shape.size() != 4 || v->shape[0] != F || v->shape[1] != 3 || v->shape[2] != H || v->dtype != DType::f32)
      throw Error("internal: hstack_videos needs f32 [F,3,H,W] inputs of equal F and H");
    W += v->shape[3];
  }
  HostTensor out({F, 3, H, W}, DType::f32);
  int64_t x0 = 0;
  for (const HostTensor* v : videos) {
    const int64_t w = v->shape[3];
    for (int64_t fc = 0; fc < F * 3; ++fc)
      for (int64_t y = 0; y < H; ++y)
        std::memcpy(out.as<float>() + (fc * H + y) * W + x0, v->as<float>() + (fc * H + y) * w, size_t(w) * 4);
    x0 += w;
  }
  return out;
}

std::string video_library_version() {
  const VideoBackend* backend = video_backend();
  return backend ? backend->library_version() : "none (no video component: only .npy frame arrays)";
}

}  // namespace dvs
