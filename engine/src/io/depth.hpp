// Per-frame depth input for the renderer: arrays [N,H,W] of disparity (the default, what
// Video-Depth-Anything writes) or metric depth, turned into float32 depth [N,H,W].
//
// Files: .npy ([N,H,W] or [N,1,H,W]; f32, f16, or f64 narrowed to f32), .npz (key "depths", else the only
// array; read with libzip), and a folder of per-frame 16-bit PNG or EXR images (depth_images.hpp, OpenCV).
// Disparity → depth exactly as the official code (float32): dn = (d − min)/(max − min) over the WHOLE clip,
// z = 10000 / max(3900·dn, 1e-5), clipped to [near, far] = [1e-4, 1e4]. Metric depth is used as is.
// Errors name the file and the problem (wrong rank or dtype, zero frames, NaN/inf with its frame, a
// constant disparity clip, non-positive metric depth).
#pragma once
#include <filesystem>
#include <string>

#include "io/host_tensor.hpp"

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

// A grayscale depth video as [N,H,W] f32 values 0..255 (disparity unless told otherwise).
HostTensor read_depth_video(const std::filesystem::path& path);

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

// Depth at the centre pixel (row H/2, column W/2) of frame 0: the official orbit radius before the cap
// (row 288, column 512 at 576×1024).
float centre_depth(const HostTensor& depth);

}  // namespace dvs
