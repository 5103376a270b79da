// The video component's reader and writer of video files, on OpenCV's FFmpeg backend: decode to f32 RGB frames at
// a working size (or u8 RGB as they are), encode frames to .mp4. The core's read_video/write_video (io/video.hpp)
// call these through the VideoBackend table (video_component.cpp) after handling .npy frame arrays themselves.
#include "video/opencv_video.hpp"

#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "dvs/error.hpp"
#include "io/disk_space.hpp"
#include "io/injected_faults.hpp"
#include "io/pixel_levels.hpp"
#include "io/third_party_logs.hpp"
#include "io/video_probe.hpp"

namespace dvs {

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
std::vector<cv::Mat> decode_frames(cv::VideoCapture& cap, const std::string& name, int max_frames, bool fewer_frames_ok,
                                   VideoInfo& vi, const std::function<cv::Mat(const cv::Mat&)>& fit) {
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
  if (max_frames > 0 && int(frames.size()) < max_frames && !fewer_frames_ok)
    throw_too_few_frames(name, int(frames.size()), max_frames, vi.frames_in_file);
  vi.frames = int(frames.size());
  if (max_frames <= 0) {
    // Read to the end. Some containers only estimate their count (from the duration), hence the one frame of slack.
    if (vi.frames_in_file > vi.frames + 1)
      vi.warnings.push_back(name + ": its header announces " + std::to_string(vi.frames_in_file) +
                            " frames but decoding stops after frame " + std::to_string(vi.frames) +
                            " (the file is truncated or damaged); using those " + std::to_string(vi.frames));
    vi.frames_in_file = vi.frames;  // exact
  } else if (vi.frames < max_frames) {
    vi.frames_in_file = vi.frames;  // decoding stopped before max_frames (fewer_frames_ok): exact
  }
  return frames;
}

}  // namespace

HostTensor opencv_read_video(const std::filesystem::path& path, const VideoReadOptions& o, VideoInfo* info) {
  const std::string name = path.string();
  VideoInfo vi;
  cv::VideoCapture cap = open_video(path, vi);
  const int w = o.width > 0 ? o.width : vi.width, h = o.height > 0 ? o.height : vi.height;
  const std::vector<cv::Mat> frames =
      decode_frames(cap, name, o.max_frames, o.fewer_frames_ok, vi, [&](const cv::Mat& m) { return fit_frame(m, w, h, o.resize); });
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

HostTensor opencv_read_video_rgb8(const std::filesystem::path& path, int max_frames, int max_long_side, VideoInfo* info) {
  return opencv_read_video_rgb8(path, max_frames, max_long_side, info, false);
}

HostTensor opencv_read_video_rgb8(const std::filesystem::path& path, int max_frames, int max_long_side, VideoInfo* info,
                                  bool fewer_frames_ok) {
  VideoInfo vi;
  cv::VideoCapture cap = open_video(path, vi);
  int w = vi.width, h = vi.height;
  if (max_long_side > 0 && std::max(w, h) > max_long_side) {
    // Video-Depth-Anything's run.py (OpenCV reader): both sides scaled by max_res / long side, Python round.
    const double s = double(max_long_side) / std::max(w, h);
    w = int(std::nearbyint(vi.width * s));
    h = int(std::nearbyint(vi.height * s));
  }
  const std::vector<cv::Mat> frames = decode_frames(cap, path.string(), max_frames, fewer_frames_ok, vi, [&](const cv::Mat& m) {
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

void opencv_write_video(const std::filesystem::path& path, const HostTensor& frames, double fps) {
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

}  // namespace dvs
