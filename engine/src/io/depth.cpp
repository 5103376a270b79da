#include "io/depth.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <vector>

#include "dvs/error.hpp"
#include "io/video.hpp"
#include "io/depth_images.hpp"
#include "io/npy.hpp"
#include "io/option_names.hpp"

#include <zip.h>

namespace dvs {

namespace {

std::string lower_ext(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

// The bytes of the .npy member `key`.npy (else `depths.npy`, else the only member) of a .npz archive.
std::vector<uint8_t> read_npz_member(const std::filesystem::path& path, const std::string& key, std::string& member) {
  int code = 0;
  zip_t* za = zip_open(path.string().c_str(), ZIP_RDONLY, &code);
  if (!za) {
    zip_error_t e;
    zip_error_init_with_code(&e, code);
    std::string msg = zip_error_strerror(&e);
    zip_error_fini(&e);
    throw Error(path.string() + ": not a readable .npz (zip) archive: " + msg);
  }
  struct Closer {
    zip_t* z;
    ~Closer() { zip_discard(z); }
  } closer{za};
  zip_int64_t n = zip_get_num_entries(za, 0);
  std::vector<std::string> names;
  for (zip_int64_t i = 0; i < n; ++i) {
    const char* nm = zip_get_name(za, zip_uint64_t(i), 0);
    if (nm) names.push_back(nm);
  }
  auto member_list = [&] {
    std::string list;
    for (auto& s : names) list += " " + s;
    return list.empty() ? std::string(" none") : list;
  };
  zip_int64_t index = -1;
  if (!key.empty()) {
    const std::string wanted = key.size() > 4 && key.compare(key.size() - 4, 4, ".npy") == 0 ? key : key + ".npy";
    index = zip_name_locate(za, wanted.c_str(), 0);
    if (index < 0) throw Error(path.string() + ": has no array '" + key + "' (members:" + member_list() + ")");
  } else {
    index = zip_name_locate(za, "depths.npy", 0);
  }
  if (index < 0) {
    if (names.size() != 1) {
      std::string list;
      for (auto& s : names) list += " " + s;
      throw Error(path.string() + ": .npz has no array 'depths' and not exactly one array (members:" +
                  (list.empty() ? std::string(" none") : list) + "); pick one with --depth " + path.string() + ":KEY");
    }
    index = 0;
  }
  member = zip_get_name(za, zip_uint64_t(index), 0);
  zip_stat_t st;
  zip_stat_init(&st);
  if (zip_stat_index(za, zip_uint64_t(index), 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE) || !(st.valid & ZIP_STAT_COMP_SIZE))
    throw Error(path.string() + ": cannot read the size of member " + member);
  if (st.size > (uint64_t(1) << 36)) throw Error(path.string() + ": member " + member + " claims an absurd size");
  // The size is the archive's claim: the buffer below is sized from it, so it must fit what the member's
  // compressed bytes can expand to (deflate at most ~1032:1) and those bytes must fit in the file (as pth_file.cpp).
  std::error_code size_error;
  const uint64_t file_size = std::filesystem::file_size(path, size_error);
  if (size_error || st.comp_size > file_size || st.size / 1100 > st.comp_size + 1)
    throw Error(path.string() + ": member " + member + " claims " + std::to_string(st.size) + " bytes (" +
                std::to_string(st.comp_size) + " compressed) in a " + std::to_string(file_size) +
                "-byte file: corrupt archive; re-save it with numpy.savez");
  std::vector<uint8_t> bytes(size_t(st.size));
  zip_file_t* f = zip_fopen_index(za, zip_uint64_t(index), 0);
  if (!f) throw Error(path.string() + ": cannot open member " + member + ": " + zip_strerror(za));
  zip_int64_t got = zip_fread(f, bytes.data(), bytes.size());
  std::string ferr = got < 0 ? zip_file_strerror(f) : "";
  zip_fclose(f);
  if (got < 0 || zip_uint64_t(got) != st.size)
    throw Error(path.string() + ": member " + member + " is truncated or corrupt" + (ferr.empty() ? "" : ": " + ferr));
  return bytes;
}

}  // namespace

std::pair<std::filesystem::path, std::string> split_npz_key(const std::filesystem::path& spec) {
  const std::string s = spec.string();
  const auto colon = s.rfind(':');
  std::error_code ec;
  if (colon == std::string::npos || std::filesystem::exists(spec, ec)) return {spec, ""};
  const std::filesystem::path file = s.substr(0, colon);
  if (lower_ext(file) != ".npz" || colon + 1 >= s.size()) return {spec, ""};
  return {file, s.substr(colon + 1)};
}

bool depth_source_exists(const std::filesystem::path& spec) {
  std::error_code ec;
  return std::filesystem::exists(split_npz_key(spec).first, ec);
}

// A grayscale depth video (what many depth tools export for viewing): the luma of each frame, 0..255.
HostTensor read_depth_video(const std::filesystem::path& path) {
  HostTensor rgb = read_video(path);  // [N,3,H,W] in [−1,1]
  const int64_t N = rgb.shape[0], H = rgb.shape[2], W = rgb.shape[3], plane = H * W;
  HostTensor out({N, H, W}, DType::f32);
  for (int64_t f = 0; f < N; ++f) {
    int64_t coloured = 0;
    for (int64_t i = 0; i < plane; ++i) {
      const float* p = rgb.as<float>() + f * 3 * plane + i;
      const float lo = std::min({p[0], p[plane], p[2 * plane]}), hi = std::max({p[0], p[plane], p[2 * plane]});
      if ((hi - lo) * 127.5f > float(kGrayTolerance)) ++coloured;
    }
    if (coloured * 100 > plane)
      throw Error(path.string() + ": frame " + std::to_string(f) + " is in colour (" +
                  std::to_string(coloured * 100 / plane) + "% of its pixels have R, G, B differing by more than " +
                  std::to_string(kGrayTolerance) +
                  " levels): a colour-mapped depth visualisation cannot be read back as depth. Give the depth model's "
                  "raw output (.npy/.npz, 16-bit PNG or EXR frames) or a grayscale video");
  }
  for (int64_t f = 0; f < N; ++f)
    for (int64_t i = 0; i < plane; ++i) {
      const float* p = rgb.as<float>() + f * 3 * plane + i;
      const float gray = (p[0] + p[plane] + p[2 * plane]) / 3.0f;  // channels are equal for a gray video
      out.as<float>()[f * plane + i] = std::round((gray + 1.0f) * 127.5f);
    }
  return out;
}

HostTensor read_depth_array(const std::filesystem::path& spec) {
  const auto [path, key] = split_npz_key(spec);
  const std::string name = path.string();
  if (!std::filesystem::exists(path)) throw Error(name + ": no such depth file");
  std::string ext = lower_ext(path);
  HostTensor t;
  if (std::filesystem::is_directory(path)) {
    t = read_depth_image_sequence(path);
  } else if (ext == ".npy") {
    t = read_npy(path);
  } else if (ext == ".npz") {
    std::string member;
    std::vector<uint8_t> bytes = read_npz_member(path, key, member);
    t = parse_npy(bytes, name + ":" + member);
  } else if (ext == ".mp4" || ext == ".mov" || ext == ".mkv" || ext == ".avi" || ext == ".webm") {
    t = read_depth_video(path);
  } else {
    throw Error(name + ": unsupported depth file type '" + ext +
                "' (expected .npy or .npz holding [N,H,W], a grayscale video, or a folder of .png / .exr frames)");
  }
  if (t.shape.size() == 4 && t.shape[1] == 1) t.shape = {t.shape[0], t.shape[2], t.shape[3]};
  else if (t.shape.size() == 4 && t.shape[3] == 1) t.shape = {t.shape[0], t.shape[1], t.shape[2]};  // [N,H,W,1]
  if (t.shape.size() != 3)
    throw Error(name + ": depth must be a [N,H,W] array (frames, rows, columns; [N,1,H,W] and [N,H,W,1] also "
                "work), got shape [" + shape_str(t.shape) + "]");
  if (t.dtype == DType::i32 || t.dtype == DType::u8) {  // 16-bit / 8-bit depth maps: their values, as floats
    std::vector<float> v(size_t(t.numel()));
    for (size_t i = 0; i < v.size(); ++i)
      v[i] = t.dtype == DType::u8 ? float(t.as<uint8_t>()[i]) : float(t.as<int32_t>()[i]);
    t = HostTensor::from_f32(t.shape, v);
  }
  if (t.dtype != DType::f32 && t.dtype != DType::f16)
    throw Error(name + ": depth must be float32, float16 or an integer type, got " + std::string(dtype_name(t.dtype)));
  if (t.shape[0] < 1) throw Error(name + ": the depth array has zero frames");
  if (t.shape[1] < 1 || t.shape[2] < 1) throw Error(name + ": the depth frames are empty [" + shape_str(t.shape) + "]");
  if (t.dtype == DType::f16) {
    std::vector<float> v = t.to_f32();
    t = HostTensor::from_f32(t.shape, v);
  }
  return t;
}

HostTensor depth_from_array(const HostTensor& in, const std::string& name, const DepthOptions& o) {
  if (in.shape.size() != 3 || in.dtype != DType::f32)
    throw Error(name + ": depth must be f32 [N,H,W], got " + std::string(dtype_name(in.dtype)) + "[" + shape_str(in.shape) + "]");
  if (in.shape[0] < 1) throw Error(name + ": the depth array has zero frames");
  const int64_t frames = in.shape[0], plane = in.shape[1] * in.shape[2];
  const float* d = in.as<float>();
  float lo = INFINITY, hi = -INFINITY;
  for (int64_t f = 0; f < frames; ++f)
    for (int64_t i = 0; i < plane; ++i) {
      float v = d[f * plane + i];
      if (!std::isfinite(v))
        throw Error(name + ": frame " + std::to_string(f) + " contains " + (std::isnan(v) ? "NaN" : "an infinite value") +
                    " at row " + std::to_string(i / in.shape[2]) + ", column " + std::to_string(i % in.shape[2]));
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
  HostTensor out(in.shape, DType::f32);
  float* z = out.as<float>();
  const int64_t n = frames * plane;
  if (o.values == DepthValues::depth) {
    for (int64_t i = 0; i < n; ++i) {
      if (!(d[i] > 0))
        throw Error(name + ": metric depth must be > 0, found " + std::to_string(d[i]) + " in frame " +
                    std::to_string(i / plane) + " (is this disparity? then do not mark it as depth)");
      z[i] = d[i] * o.metric_scale;
    }
    return out;
  }
  if (lo < 0) {  // disparity is inverse depth: a depth model's output is never negative (VDA ends in a ReLU)
    int64_t first = 0, count = 0;
    for (int64_t i = n - 1; i >= 0; --i)
      if (d[i] < 0) first = i, ++count;
    throw Error(name + ": disparity (inverse depth) cannot be negative, but frame " + std::to_string(first / plane) +
                " holds " + std::to_string(d[first]) + " at row " + std::to_string(first % plane / in.shape[2]) +
                ", column " + std::to_string(first % in.shape[2]) + " (" + std::to_string(count) + " of " +
                std::to_string(n) + " values are below 0, the least " + std::to_string(lo) +
                "). Give a depth model's raw disparity; if the file holds metric depth, say so with " +
                option_name("RenderJob::metric_depth") + "; a signed or log map must be converted first");
  }
  if (!(hi > lo))
    throw Error(name + ": the disparity is constant over the whole clip (" + std::to_string(lo) +
                "), so it cannot be normalised into depth");
  // float32 throughout, in the order numpy evaluates it.
  const float range = hi - lo;
  for (int64_t i = 0; i < n; ++i) {
    float dn = (d[i] - lo) / range;
    float zz = 10000.0f / std::max(3900.0f * dn, 1e-5f);
    z[i] = std::clamp(zz, o.near_clip, o.far_clip);
  }
  return out;
}

HostTensor load_depth(const std::filesystem::path& path, const DepthOptions& options) {
  return depth_from_array(read_depth_array(path), path.string(), options);
}

namespace {

// Bilinear resampling of the region [x0, x0+rw) × [y0, y0+rh) (pixel units, may be fractional) of every
// frame onto height × width, half-pixel centres.
HostTensor resample_region(const HostTensor& depth, double x0r, double y0r, double rw, double rh, int height, int width) {
  const int64_t N = depth.shape[0], H = depth.shape[1], W = depth.shape[2];
  HostTensor out({N, height, width}, DType::f32);
  const float* s = depth.as<float>();
  float* o = out.as<float>();
  const double sy = rh / height, sx = rw / width;
  for (int64_t f = 0; f < N; ++f)
    for (int y = 0; y < height; ++y) {
      double fy = std::max(y0r + (y + 0.5) * sy - 0.5, 0.0);
      int64_t y0 = std::min<int64_t>(int64_t(fy), H - 1), y1 = std::min<int64_t>(y0 + 1, H - 1);
      double wy = fy - double(y0);
      for (int x = 0; x < width; ++x) {
        double fx = std::max(x0r + (x + 0.5) * sx - 0.5, 0.0);
        int64_t x0 = std::min<int64_t>(int64_t(fx), W - 1), x1 = std::min<int64_t>(x0 + 1, W - 1);
        double wx = fx - double(x0);
        const float* p = s + f * H * W;
        double v = (1 - wy) * ((1 - wx) * p[y0 * W + x0] + wx * p[y0 * W + x1]) +
                   wy * ((1 - wx) * p[y1 * W + x0] + wx * p[y1 * W + x1]);
        o[(f * height + y) * width + x] = float(v);
      }
    }
  return out;
}

// The first `frames` frames (allow_trim) or all of them; fewer depth frames than video frames is an error.
HostTensor cut_frames(const HostTensor& depth, int frames, bool allow_trim, const std::string& name) {
  if (depth.shape.size() != 3 || depth.dtype != DType::f32) throw Error(name + ": depth must be f32 [N,H,W]");
  if (frames < 1) throw Error(name + ": the video has no frames");
  const int64_t N = depth.shape[0];
  if (N < frames)
    throw Error(name + ": has " + std::to_string(N) + " depth frames but the video has " + std::to_string(frames));
  HostTensor d = depth;
  if (N > frames) {
    if (!allow_trim)
      throw Error(name + ": has " + std::to_string(N) + " depth frames but the video has " + std::to_string(frames) +
                  " (" + option_name("RenderJob::trim_depth") + " uses its first " + std::to_string(frames) + ")");
    d.shape[0] = frames;
    d.data.resize(size_t(frames) * size_t(depth.shape[1] * depth.shape[2]) * 4);
  }
  return d;
}

}  // namespace

HostTensor resize_depth(const HostTensor& depth, int height, int width) {
  if (depth.shape.size() != 3 || depth.dtype != DType::f32) throw Error("resize_depth: expected f32 [N,H,W]");
  if (height < 1 || width < 1) throw Error("resize_depth: the target size must be positive");
  const int64_t H = depth.shape[1], W = depth.shape[2];
  if (H == height && W == width) return depth;
  return resample_region(depth, 0, 0, double(W), double(H), height, width);
}

DepthFit parse_depth_fit(const std::string& v) {
  if (v == "error") return DepthFit::error;
  if (v == "stretch") return DepthFit::stretch;
  if (v == "crop") return DepthFit::crop;
  throw Error(option_name("RenderJob::depth_fit") + " must be error, stretch or crop, got '" + v + "'");
}

const char* depth_fit_name(DepthFit fit) {
  return fit == DepthFit::stretch ? "stretch" : fit == DepthFit::crop ? "crop" : "error";
}

DepthRegion depth_region_for_video(int64_t depth_height, int64_t depth_width, const VideoFrameGeometry& g, DepthFit fit,
                                   const std::string& name) {
  if (g.source_height < 1 || g.source_width < 1 || g.height < 1 || g.width < 1)
    throw Error(name + ": internal: the video's frame size is unknown");
  const double dh = double(depth_height), dw = double(depth_width);
  const double vh = g.source_height, vw = g.source_width;
  // 1. The depth region that covers the source video frame.
  double rx = 0, ry = 0, rw = dw, rh = dh;
  const double depth_aspect = dw / dh, video_aspect = vw / vh;
  if (std::abs(depth_aspect / video_aspect - 1.0) > kDepthAspectTolerance) {
    auto shape = [](double h, double w) { return std::to_string(int64_t(h)) + "x" + std::to_string(int64_t(w)); };
    if (fit == DepthFit::error)
      throw Error(name + ": the depth frames are " + shape(dh, dw) + " (HxW) but the video's are " + shape(vh, vw) +
                  ": another aspect ratio" + (((dw > dh) != (vw > vh)) ? " and orientation" : "") +
                  ", so depth and pixels would not line up. Give depth computed on this video, or say how to map "
                  "it: " + option_name("RenderJob::depth_fit") + " stretch (scale each axis) or crop (cut the depth's centre)");
    if (fit == DepthFit::crop) {
      if (depth_aspect > video_aspect) rw = dh * video_aspect;
      else rh = dw / video_aspect;
      rx = (dw - rw) / 2;
      ry = (dh - rh) / 2;
    }
  }
  // 2. The part of the source frame the video kept (video.cpp's fit_frame, in source pixels).
  double cx = 0, cy = 0, cw = vw, ch = vh;
  if (g.resize == ResizeMode::crop && !(g.source_width == g.width && g.source_height == g.height)) {
    const double s = std::max(double(g.width) / vw, double(g.height) / vh);
    const int icw = std::min(g.source_width, int(std::lround(g.width / s)));
    const int ich = std::min(g.source_height, int(std::lround(g.height / s)));
    cx = double((g.source_width - icw) / 2);
    cy = double((g.source_height - ich) / 2);
    cw = icw;
    ch = ich;
  }
  const double kx = rw / vw, ky = rh / vh;
  const double x0 = rx + cx * kx, y0 = ry + cy * ky, w = cw * kx, h = ch * ky;
  // 3. Enough depth for the video: one depth pixel may stand for at most kDepthMaxUpscale pixels a side of the
  // video's own frame (the part it keeps). Against the source, not the working size: depth at the video's own
  // resolution always passes, whatever --size upscales both to.
  if (h * kDepthMaxUpscale < ch || w * kDepthMaxUpscale < cw) {
    char ratio[32];
    std::snprintf(ratio, sizeof ratio, "%.3g", std::max(ch / h, cw / w));
    throw Error(name + ": the depth frames are " + std::to_string(depth_height) + "x" + std::to_string(depth_width) +
                " (HxW), far too small for the video's " + std::to_string(g.source_height) + "x" +
                std::to_string(g.source_width) + " frames: each depth pixel would cover " + ratio +
                " video pixels a side (at most " + std::to_string(kDepthMaxUpscale) +
                " are allowed). Give depth computed at (or near) the video's size, e.g. with dvs depth or --depth-model");
  }
  return {x0, y0, w, h};
}

HostTensor map_depth_to_video(const HostTensor& depth, int frames, const VideoFrameGeometry& g, DepthFit fit,
                              bool allow_trim, const std::string& name) {
  const HostTensor d = cut_frames(depth, frames, allow_trim, name);
  const DepthRegion r = depth_region_for_video(d.shape[1], d.shape[2], g, fit, name);
  if (r.x0 == 0 && r.y0 == 0 && r.w == double(d.shape[2]) && r.h == double(d.shape[1])) return resize_depth(d, g.height, g.width);
  return resample_region(d, r.x0, r.y0, r.w, r.h, g.height, g.width);
}

HostTensor fit_depth_to_video(const HostTensor& depth, int frames, int height, int width, bool allow_trim,
                              const std::string& name) {
  return resize_depth(cut_frames(depth, frames, allow_trim, name), height, width);
}

float centre_depth(const HostTensor& depth) {
  if (depth.shape.size() != 3 || depth.dtype != DType::f32 || depth.numel() == 0)
    throw Error("centre_depth: expected f32 [N,H,W] with at least one frame");
  const int64_t H = depth.shape[1], W = depth.shape[2];
  return depth.as<float>()[(H / 2) * W + W / 2];
}

}  // namespace dvs
