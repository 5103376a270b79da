// Per-frame depth input for the renderer: arrays [N,H,W] of disparity (the default, what
// Video-Depth-Anything writes) or metric depth, turned into float32 depth [N,H,W].
//
// Files: .npy ([N,H,W], [N,1,H,W] or [N,H,W,1]; f32, f16, f64 narrowed to f32, or integers — u8, u16, i32 —
// taken as their values), .npz (FILE.npz:KEY picks the array KEY; else key "depths", else the only array;
// read with libzip), a folder of per-frame 16-bit PNG or EXR images in natural name order
// (depth_images.hpp, OpenCV), and a grayscale video (a colour video, e.g. a colour-mapped depth
// visualisation, is refused: its luma is not the depth).
// Disparity → depth exactly as the official code (float32): dn = (d − min)/(max − min) over the WHOLE clip,
// z = 10000 / max(3900·dn, 1e-5), clipped to [near, far] = [1e-4, 1e4]. Metric depth is used as is.
// Errors name the file and the problem (wrong rank or dtype, zero frames, NaN/inf with its frame, a
// constant disparity clip, negative disparity, non-positive metric depth).
#pragma once
#include <filesystem>
#include <string>

#include "io/host_tensor.hpp"
#include "io/video.hpp"

namespace dvs {

enum class DepthValues { disparity, depth };

struct DepthOptions {
  DepthValues values = DepthValues::disparity;
  float near_clip = 1e-4f, far_clip = 1e4f;  // disparity conversion only
  float metric_scale = 1.0f;                 // metric depth is multiplied by this (0.001 for PNGs in mm)
};

// The stored array as f32 [N,H,W], validated (rank, dtype, N ≥ 1, finite).
HostTensor read_depth_array(const std::filesystem::path& path);

// Validates and converts an array already in memory; `name` is used in error messages.
HostTensor depth_from_array(const HostTensor& values, const std::string& name, const DepthOptions& options = {});

// A grayscale depth video as [N,H,W] f32 values 0..255 (disparity unless told otherwise). Gray means every
// pixel's R, G and B agree within kGrayTolerance levels (video coding leaves small differences); a video
// where more than 1% of the pixels of a frame differ more is refused, naming the frame.
HostTensor read_depth_video(const std::filesystem::path& path);
constexpr int kGrayTolerance = 12;

// `--depth FILE.npz:KEY`: (FILE.npz, KEY) when `spec` names an array inside an .npz that exists, else
// (spec, ""). A file whose own name contains ':' wins when it exists.
std::pair<std::filesystem::path, std::string> split_npz_key(const std::filesystem::path& spec);

// Whether the depth file or folder `spec` names exists (FILE.npz:KEY: the .npz).
bool depth_source_exists(const std::filesystem::path& spec);

// read_depth_array + depth_from_array.
HostTensor load_depth(const std::filesystem::path& path, const DepthOptions& options = {});

// Bilinear resize of every frame of [N,H,W] f32 to [N,height,width] (half-pixel centres, like
// F.interpolate(align_corners=False)); for depth of another size than the video.
HostTensor resize_depth(const HostTensor& depth, int height, int width);

// Fits converted depth [N,H,W] to a video of `frames` frames of height × width: another size is resampled
// (resize_depth); more depth frames than video frames is an error unless allow_trim (then the first
// `frames` are kept — after the disparity conversion, so the normalisation still spans the whole clip, as
// in the official code); fewer is always an error. Errors name `name`.
HostTensor fit_depth_to_video(const HostTensor& depth, int frames, int height, int width, bool allow_trim,
                              const std::string& name);

// How depth of another aspect ratio (or orientation) than the video is mapped onto it: `error` (the default:
// refuse, naming both shapes), `stretch` (scale each axis to the video frame), `crop` (cut the depth's
// centre to the video's aspect ratio). Aspect ratios within kDepthAspectTolerance (relative) count as equal
// (depth models round sizes, e.g. to multiples of 14) and are scaled.
enum class DepthFit { error, stretch, crop };
constexpr double kDepthAspectTolerance = 0.02;
DepthFit parse_depth_fit(const std::string& value);  // "error" | "stretch" | "crop"; dvs::Error otherwise
const char* depth_fit_name(DepthFit fit);

// How the video was brought to the working size: its size in the file and the resize rule.
struct VideoFrameGeometry {
  int source_height = 0, source_width = 0;  // the video file's frame
  int height = 0, width = 0;                // the working size
  ResizeMode resize = ResizeMode::crop;
};

// Depth [N,h,w] mapped onto the working frame exactly as the video's frames were (so depth pixel and video
// pixel stay aligned under --resize crop): first onto the source video frame (DepthFit when the aspect
// ratios differ), then the video's own crop or squash, then bilinear resampling (half-pixel centres).
// Depth whose part that covers the video's frame (in the video's own pixels) has fewer than 1/kDepthMaxUpscale of
// its rows or columns is refused (e.g. 4x7 for 384x672: one depth pixel per 96x96 pixels is no geometry). Frame counts as
// fit_depth_to_video. Errors name `name`.
constexpr int kDepthMaxUpscale = 8;
// The region of a depth frame of depth_height × depth_width (its pixels, x0 y0 w h) that map_depth_to_video
// resamples onto the working frame; dvs::Error (naming `name`) for depth it refuses: another aspect ratio under
// DepthFit::error, far too small. Preflight calls it with the depth file's header shape, before any work.
struct DepthRegion {
  double x0 = 0, y0 = 0, w = 0, h = 0;
};
DepthRegion depth_region_for_video(int64_t depth_height, int64_t depth_width, const VideoFrameGeometry& video, DepthFit fit,
                                   const std::string& name);
HostTensor map_depth_to_video(const HostTensor& depth, int frames, const VideoFrameGeometry& video, DepthFit fit,
                              bool allow_trim, const std::string& name);

// Depth at the centre pixel (row H/2, column W/2) of frame 0: the official orbit radius before the cap
// (row 288, column 512 at 576×1024).
float centre_depth(const HostTensor& depth);

}  // namespace dvs
