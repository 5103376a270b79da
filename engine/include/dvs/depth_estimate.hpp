// Video depth inside dvs: Video-Depth-Anything (github DepthAnything/Video-Depth-Anything) run as GLSL compute on
// a clip, written as its run.py --save_npz writes it (disparity [N, H, W] f32 under key "depths"), so a plain
// video is all `dvs run` / `dvs render` need (--depth-model instead of --depth).
#pragma once
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "dvs/pipeline.hpp"

namespace dvs {

struct DepthJob {
  std::filesystem::path video;
  std::filesystem::path model;  // video_depth_anything_vit{s,b,l}.pth (or metric_...), or a .safetensors of it
  int input_size = 518;         // run.py --input_size
  int frames = 0;               // first N frames; 0 = all (run.py --max_len)
  int max_res = 1280;           // frames whose long side exceeds this are scaled down first (run.py --max_res)
  std::optional<bool> metric;   // unset: the checkpoint's mode (metric_* files are metric)
  std::string device;
};

struct DepthSummary {
  int frames = 0, height = 0, width = 0;  // the depth's size (the frames' size after max_res)
  int input_height = 0, input_width = 0;  // the network input
  int windows = 0;
  std::string model_size;                 // "vits", ... or the config's name
  bool metric = false;
  uint64_t weight_bytes = 0, peak_device_bytes = 0;
  double seconds_decode = 0, seconds_load = 0, seconds_depth = 0;
};

// Estimates the depth of job.video and writes it to `out` (.npz: key "depths"; .npy: the array), atomically.
// Progress: stage "depth", one step per window. Throws dvs::Error naming the file at fault.
DepthSummary estimate_depth(const DepthJob& job, const std::filesystem::path& out, const ProgressFn& progress = {},
                            const CancelFn& cancelled = {});

// A cached estimate for (video bytes, model file, input size, frames, max_res, metric): the cached .npy's path
// when present (from_cache = true), else estimated now and stored there. cache_dir empty: $DVS_CACHE_DIR or
// ~/.cache/dvs; refresh = true re-estimates even when an entry exists (--no-cache).
struct CachedDepth {
  std::filesystem::path file;
  bool from_cache = false;
  std::string key;
  DepthSummary summary;  // of the estimate (only when computed now)
};
CachedDepth cached_depth(const DepthJob& job, const std::filesystem::path& cache_dir, bool refresh,
                         const ProgressFn& progress = {}, const CancelFn& cancelled = {});

}  // namespace dvs
