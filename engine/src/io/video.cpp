#include "io/video.hpp"

#ifndef DVS_VIDEO_IO
#define DVS_VIDEO_IO 1  // CMake defines it as 0 for this file in a DVS_VIDEO_IO=OFF build
#endif

#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <iostream>
#if DVS_VIDEO_IO
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#endif

#include "dvs/error.hpp"
#include "io/disk_space.hpp"
#include "io/injected_faults.hpp"
#include "io/npy.hpp"
#include "io/pixel_levels.hpp"
#include "io/third_party_logs.hpp"
#include "io/video_probe.hpp"

namespace dvs {

// Frame arrays: every build reads a "video" that is an .npy file (recognised by its contents, whatever its name)
// of f32 [F,3,H,W] in [-1,1] or u8 [F,H,W,3] RGB, at its own size (no resizing): frames in as arrays, for the
// GPU bundle's end-to-end run. Without OpenCV (DVS_VIDEO_IO=OFF) write_video stores the frames that way too,
// under the name it is given (output.mp4 then holds an .npy), and other files are refused.
namespace {

[[noreturn]] void no_video_io(const std::filesystem::path& path, const std::string& what) {
  throw Error(path.string() + ": " + what + (DVS_VIDEO_IO ? " (frame arrays are read at their own size)"
                                                          : ": built without video I/O (DVS_VIDEO_IO=OFF; only .npy frame arrays)"));
}

// A video that holds fewer frames than were asked for (--frames). `announced` is the container's own count (0 when
// it does not say); more than were decoded means the file stops early. run needs 4k+1 frames, render and depth
// take any count, so both are suggested.
[[noreturn]] void too_few_frames(const std::string& name, int have, int wanted, int announced) {
  const int fit = (have - 1) / 4 * 4 + 1;
  std::string why;
  if (announced > have)
    why = " (the file is truncated or damaged: its header announces " + std::to_string(announced) +
          " frames but decoding stops after frame " + std::to_string(have) + ")";
  throw Error(name + ": holds " + std::to_string(have) + " frames, fewer than --frames " + std::to_string(wanted) + why +
              "; use --frames " + std::to_string(fit) + " (the largest 4k+1 it has, as dvs run needs; dvs render and "
              "dvs depth take any count up to " + std::to_string(have) + "), or leave --frames out to use them all");
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
  if (max_frames > 0 && F < max_frames) too_few_frames(path.string(), int(F), max_frames, 0);
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

}  // namespace


#if DVS_VIDEO_IO
namespace {

// Resizes one BGR frame to (w, h) by the chosen rule. Shrinking uses area averaging (no aliasing),
// enlarging bilinear.
cv::Mat fit_frame(const cv::Mat& in, int w, int h, ResizeMode mode) {
  if (w <= 0 || h <= 0 || (in.cols == w && in.rows == h)) return in;
  cv::Mat src = in;
  if (mode == ResizeMode::crop) {
    double s = std::max(double(w) / in.cols, double(h) / in.rows);
    int cw = std::min(in.cols, int(std::lround(w / s))), ch = std::min(in.rows, int(std::lround(h / s)));
    src = in(cv::Rect((in.cols - cw) / 2, (in.rows - ch) / 2, cw, ch));
  }
  cv::Mat out;
  bool shrink = src.cols >= w && src.rows >= h;
  cv::resize(src, out, cv::Size(w, h), 0, 0, shrink ? cv::INTER_AREA : cv::INTER_LINEAR);
  return out;
}

// While alive, memory that malloc hands out is filled with a fixed byte. The H.264 encoder (OpenCV's FFmpeg
// writer with x264) reads some memory it never wrote, so the same frames gave different bytes from run to run
// (measured: 1 file in 6 to 8 on this machine; with the heap filled, 40 of 40 identical), which broke
// reproducible runs. The fill costs a memset of the encoder's buffers, a few MB per video.
class FilledAllocations {
 public:
  FilledAllocations() {
#ifdef __GLIBC__
    mallopt(M_PERTURB, 0x5a);
#endif
  }
  ~FilledAllocations() {
#ifdef __GLIBC__
    mallopt(M_PERTURB, 0);
#endif
  }
  FilledAllocations(const FilledAllocations&) = delete;
  FilledAllocations& operator=(const FilledAllocations&) = delete;
};

// Opens the file and reads what its container says (size, fps, frame count); errors name the file.
cv::VideoCapture open_video(const std::filesystem::path& path, VideoInfo& vi) {
  const std::string name = path.string();
  if (!std::filesystem::is_regular_file(path)) throw Error(name + ": no such video file");
  cv::VideoCapture cap(name, cv::CAP_FFMPEG);
  if (!cap.isOpened()) {
    const std::string problem = video_file_problem(path);
    if (!problem.empty())
      throw Error(name + ": cannot read the video: " + problem);
    throw Error(name + ": cannot open the video (unknown container or codec; re-encode it to H.264 .mp4, e.g. "
                "ffmpeg -i IN -c:v libx264 OUT.mp4)");
  }
  vi.width = int(cap.get(cv::CAP_PROP_FRAME_WIDTH));
  vi.height = int(cap.get(cv::CAP_PROP_FRAME_HEIGHT));
  vi.fps = cap.get(cv::CAP_PROP_FPS);
  vi.frames_in_file = std::max(0, int(cap.get(cv::CAP_PROP_FRAME_COUNT)));
  if (!(vi.fps > 0 && vi.fps < 1000)) vi.fps = 30;
  return cap;
}

// Decodes up to max_frames (0 = all) BGR frames, each passed through `fit`; records the count in vi.
std::vector<cv::Mat> decode_frames(cv::VideoCapture& cap, const std::string& name, int max_frames, VideoInfo& vi,
                                   const std::function<cv::Mat(const cv::Mat&)>& fit) {
  std::vector<cv::Mat> frames;
  cv::Mat bgr;
  while ((max_frames <= 0 || int(frames.size()) < max_frames) && cap.read(bgr)) {
    if (bgr.empty()) break;
    if (bgr.channels() == 1) cv::cvtColor(bgr, bgr, cv::COLOR_GRAY2BGR);
    frames.push_back(fit(bgr).clone());
  }
  if (frames.empty()) {
    const std::string problem = video_file_problem(name);
    throw Error(name + ": not one frame of the video can be decoded" +
                (!problem.empty() ? ": " + problem
                 : vi.frames_in_file > 0 ? " though its header announces " + std::to_string(vi.frames_in_file) +
                                               " (the file is truncated or damaged)"
                                         : std::string()) +
                (problem.empty() ? "; export or copy it again, or re-encode it (ffmpeg -i IN -c:v libx264 OUT.mp4)" : ""));
  }
  if (max_frames > 0 && int(frames.size()) < max_frames)
    too_few_frames(name, int(frames.size()), max_frames, vi.frames_in_file);
  vi.frames = int(frames.size());
  if (max_frames <= 0) {
    // Read to the end. Some containers only estimate their count (from the duration), hence the one frame of slack.
    if (vi.frames_in_file > vi.frames + 1)
      std::cerr << "dvs: warning: " << name << ": its header announces " << vi.frames_in_file
                << " frames but decoding stops after frame " << vi.frames
                << " (the file is truncated or damaged); using those " << vi.frames << "\n";
    vi.frames_in_file = vi.frames;  // exact
  }
  return frames;
}

}  // namespace

HostTensor read_video(const std::filesystem::path& path, const VideoReadOptions& o, VideoInfo* info) {
  if (std::filesystem::is_regular_file(path) && is_npy(path)) return read_video_npy(path, o, info);
  const std::string name = path.string();
  VideoInfo vi;
  cv::VideoCapture cap = open_video(path, vi);
  const int w = o.width > 0 ? o.width : vi.width, h = o.height > 0 ? o.height : vi.height;
  const std::vector<cv::Mat> frames =
      decode_frames(cap, name, o.max_frames, vi, [&](const cv::Mat& m) { return fit_frame(m, w, h, o.resize); });
  if (info) *info = vi;

  HostTensor out({int64_t(frames.size()), 3, h, w}, DType::f32);
  float* dst = out.as<float>();
  const size_t plane = size_t(h) * w;
  for (size_t f = 0; f < frames.size(); ++f) {
    const cv::Mat& m = frames[f];
    for (int y = 0; y < h; ++y) {
      const uint8_t* row = m.ptr<uint8_t>(y);
      for (int x = 0; x < w; ++x)
        for (int c = 0; c < 3; ++c)  // BGR -> RGB planes
          dst[(f * 3 + size_t(c)) * plane + size_t(y) * w + x] = level_to_unit(row[3 * x + (2 - c)]);
    }
  }
  return out;
}

HostTensor read_video_rgb8(const std::filesystem::path& path, int max_frames, int max_long_side, VideoInfo* info) {
  if (std::filesystem::is_regular_file(path) && is_npy(path)) return read_video_rgb8_npy(path, max_frames, max_long_side, info);
  VideoInfo vi;
  cv::VideoCapture cap = open_video(path, vi);
  int w = vi.width, h = vi.height;
  if (max_long_side > 0 && std::max(w, h) > max_long_side) {
    // Video-Depth-Anything's run.py (OpenCV reader): both sides scaled by max_res / long side, Python round.
    const double s = double(max_long_side) / std::max(w, h);
    w = int(std::nearbyint(vi.width * s));
    h = int(std::nearbyint(vi.height * s));
  }
  const std::vector<cv::Mat> frames = decode_frames(cap, path.string(), max_frames, vi, [&](const cv::Mat& m) {
    if (m.cols == w && m.rows == h) return m;
    cv::Mat out;
    cv::resize(m, out, cv::Size(w, h));  // cv2.resize's default (bilinear), as run.py calls it
    return out;
  });
  if (info) *info = vi;
  HostTensor out({int64_t(frames.size()), h, w, 3}, DType::u8);
  uint8_t* dst = out.as<uint8_t>();
  for (size_t f = 0; f < frames.size(); ++f) {
    cv::Mat rgb;
    cv::cvtColor(frames[f], rgb, cv::COLOR_BGR2RGB);
    for (int y = 0; y < h; ++y) std::memcpy(dst + ((f * h + size_t(y)) * w) * 3, rgb.ptr<uint8_t>(y), size_t(w) * 3);
  }
  return out;
}

void write_video(const std::filesystem::path& path, const HostTensor& frames, double fps) {
  const std::string name = path.string();
  const Shape& s = frames.shape;
  int64_t F = 0, C = 0, H = 0, W = 0;
  if (s.size() == 4 && (s[1] == 3 || s[1] == 1)) F = s[0], C = s[1], H = s[2], W = s[3];
  else if (s.size() == 3) F = s[0], C = 1, H = s[1], W = s[2];
  else throw Error("internal: write_video expects [F,3,H,W], [F,1,H,W] or [F,H,W], got [" + shape_str(s) + "]");
  if (F == 0) throw Error(name + ": no frames to write");
  std::vector<float> v = frames.to_f32();

  std::filesystem::path tmp = path.parent_path() / (path.stem().string() + ".partial-" + std::to_string(::getpid()) + path.extension().string());
  cv::VideoWriter writer;
  const FilledAllocations filled;  // the same frames give the same bytes (see FilledAllocations)
  for (const char* codec : {"avc1", "mp4v"}) {
    const QuietStderr quiet;  // OpenCV prints the codec-tag fallback with fprintf, whatever the log level
    writer.open(tmp.string(), cv::CAP_FFMPEG, cv::VideoWriter::fourcc(codec[0], codec[1], codec[2], codec[3]), fps,
                cv::Size(int(W), int(H)));
    if (writer.isOpened()) break;
  }
  const std::filesystem::path folder = path.parent_path().empty() ? std::filesystem::path(".") : path.parent_path();
  if (!writer.isOpened()) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    const std::string full = no_space_note(folder);
    if (!full.empty()) throw Error(name + ": cannot create the video: " + full);
    throw Error(name + ": cannot create the video (is the folder writable? does this OpenCV have an MP4 encoder?)");
  }
  const size_t plane = size_t(H) * W;
  cv::Mat bgr(int(H), int(W), CV_8UC3);
  for (int64_t f = 0; f < F; ++f) {
    for (int64_t y = 0; y < H; ++y) {
      uint8_t* row = bgr.ptr<uint8_t>(int(y));
      for (int64_t x = 0; x < W; ++x)
        for (int c = 0; c < 3; ++c) {
          float val = v[(size_t(f) * C + size_t(C == 3 ? c : 0)) * plane + size_t(y) * W + x];
          row[3 * x + (2 - c)] = unit_to_level(val);
        }
    }
    writer.write(bgr);
  }
  writer.release();
  std::error_code ec;
  // OpenCV does not report FFmpeg's write errors: a full disk shows only as a short file and no free space.
  std::string full = no_space_note(folder);
  if (const int injected = faults::write_error(path)) full = write_error_note(injected, folder);
  if (!full.empty() || !std::filesystem::exists(tmp, ec) || std::filesystem::file_size(tmp, ec) == 0) {
    std::filesystem::remove(tmp, ec);
    throw Error(name + ": writing the video failed: " + (full.empty() ? std::string("the encoder wrote nothing") : full));
  }
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    std::filesystem::remove(tmp, ec);
    throw Error(name + ": cannot move the finished video into place (" + ec.message() + ")");
  }
}

#else  // DVS_VIDEO_IO

HostTensor read_video(const std::filesystem::path& path, const VideoReadOptions& o, VideoInfo* info) {
  if (std::filesystem::is_regular_file(path) && !is_npy(path)) no_video_io(path, "cannot decode the video");
  return read_video_npy(path, o, info);
}

HostTensor read_video_rgb8(const std::filesystem::path& path, int max_frames, int max_long_side, VideoInfo* info) {
  if (std::filesystem::is_regular_file(path) && !is_npy(path)) no_video_io(path, "cannot decode the video");
  return read_video_rgb8_npy(path, max_frames, max_long_side, info);
}

void write_video(const std::filesystem::path& path, const HostTensor& frames, double) {
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

#endif  // DVS_VIDEO_IO

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

#if DVS_VIDEO_IO
std::string video_library_version() { return "OpenCV " + cv::getVersionString(); }
#else
std::string video_library_version() { return "none (built without video I/O, DVS_VIDEO_IO=OFF)"; }
#endif

}  // namespace dvs
