// Video depth inside dvs: Video-Depth-Anything (github DepthAnything/Video-Depth-Anything) run as GLSL compute on
// a clip, written as its run.py --save_npz writes it (disparity [N, H, W] f32 under key "depths"), so a plain
// video is all `dvs run` / `dvs render` need (--depth-model instead of --depth).
#pragma once
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "dvs/pipeline.hpp"
#include "dvs/api.hpp"

namespace dvs {

struct DepthJob {
  std::filesystem::path video;
  std::filesystem::path model;  // video_depth_anything_vit{s,b,l}.pth (or metric_...), or a .safetensors of it
  int input_size = 518;         // run.py --input_size
  int frames = 0;               // first N frames; 0 = all (run.py --max_len)
  int max_res = 1280;           // frames whose long side exceeds this are scaled down first (run.py --max_res)
  std::optional<bool> metric;   // unset: the checkpoint's mode (metric_* files are metric)
  std::string device;
  // The depth cache every estimate goes through (shared by dvs depth and --depth-model, same key), so a failed
  // write or a retry never repeats the work: the cache folder, as `--cache-dir` (dvs/cache.hpp; the entries in
  // cache_dir/inversions). Empty: $DVS_CACHE_DIR, else ~/.cache/dvs.
  std::filesystem::path cache_dir;
  bool refresh_cache = false;  // estimate again even when the cache holds this estimate (--no-cache)
  // Lines to keep apart from the progress (the forecast of a long estimate; a damaged cache entry replaced is a
  // warning to the log handler, dvs/logs.hpp).
  // Unset: sent as progress notes of stage "depth".
  std::function<void(const std::string&)> notice;
  double forecast_after_s = 60;  // forecast the cost of estimates expected to take at least this long
  std::string input_size_option = "--input-size";  // how messages name the option (run: --depth-input-size)
};

struct DepthSummary {
  int frames = 0, height = 0, width = 0;  // the depth's size (the frames' size after max_res)
  int input_height = 0, input_width = 0;  // the network input
  int windows = 0;
  std::string model_size;                 // "vits", ... or the config's name
  bool metric = false;
  uint64_t weight_bytes = 0, peak_device_bytes = 0;         // of an estimate made now
  double seconds_decode = 0, seconds_load = 0, seconds_depth = 0;
  bool from_cache = false;                                    // taken from the depth cache, not estimated now
  std::filesystem::path cache_file;
};

// One line for a person: size, model, network input, windows, times (3 digits) or where the cached one came from.
DVS_API std::string describe(const DepthSummary& summary);

// Estimates the depth of job.video (or takes it from the depth cache) and writes it to `out` (.npz: key
// "depths"; .npy: the array), atomically. `out` and the cache are checked before any work; a write that still
// fails keeps the estimate in the cache, so the same command with another --out reuses it.
// Progress: stage "depth", steps within every window (encoder blocks, head stages; note says which), polled for
// cancellation at each. A broken model (NaN/Inf or constant disparity) is a dvs::Error and nothing is cached.
// Throws dvs::Error naming the file at fault.
DVS_API DepthSummary estimate_depth(const DepthJob& job, const std::filesystem::path& out, const ProgressFn& progress = {},
                                    const CancelFn& cancelled = {});

// A cached estimate for (video bytes, model file, input size, frames, max_res, metric): the cached .npy's path
// when a sound entry is present (from_cache = true), else estimated now and stored there (job.cache_dir,
// job.refresh_cache). The cache folder is checked before the work.
struct CachedDepth {
  std::filesystem::path file;
  bool from_cache = false;
  std::string key;
  DepthSummary summary;  // of the estimate (complete only when computed now)
};
DVS_API CachedDepth cached_depth(const DepthJob& job, const ProgressFn& progress = {}, const CancelFn& cancelled = {});

// Whether the cache holds an entry for this job (not read: a damaged one is estimated again).
DVS_API bool depth_cache_has(const DepthJob& job);

}  // namespace dvs
