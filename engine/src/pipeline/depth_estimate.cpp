#include "dvs/depth_estimate.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>

#include "io/public_call.hpp"
#include "dvs/error.hpp"
#include "dvs/usage_error.hpp"
#include "io/crash_points.hpp"
#include "io/injected_faults.hpp"
#include "io/library_log.hpp"
#include "io/npy.hpp"
#include "io/npz_writer.hpp"
#include "io/option_names.hpp"
#include "io/video.hpp"
#include "models/vda/vda_memory.hpp"
#include "models/vda/vda_model.hpp"
#include "models/vda/vda_stitch.hpp"
#include "models/vda/vda_video.hpp"
#include "pipeline/cache_entry.hpp"
#include "pipeline/cache_layout.hpp"
#include "pipeline/frames_depth.hpp"
#include "pipeline/depth_source.hpp"
#include "dvs/duration_text.hpp"
#include "pipeline/inversion_cache.hpp"
#include "pipeline/output_path.hpp"
#include "pipeline/run_outputs.hpp"
#include "vk/check.hpp"
#include "vk/context.hpp"
#include "vk/memory.hpp"

namespace dvs {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// How messages name the job's input size and frames (DepthJob::input_size_option, frames_option).
std::string input_size_name(const DepthJob& j) {
  return j.input_size_option.empty() ? option_name("DepthJob::input_size") : j.input_size_option;
}
std::string frames_name(const DepthJob& j) { return j.frames_option.empty() ? option_name("DepthJob::frames") : j.frames_option; }

void check_job(const DepthJob& j) {
  if (!std::filesystem::is_regular_file(j.video))
    throw Error(j.video.string() + ": no such video file (give " + option_name("DepthJob::video") + ")");
  if (!std::filesystem::is_regular_file(j.model))
    throw Error(j.model.string() + ": no such depth model (give " + option_name("DepthJob::model") +
                " video_depth_anything_vits.pth; README.md says where the checkpoints are)");
  if (j.input_size < 14 || j.input_size > 4096)
    throw UsageError(input_size_name(j) + " must be in [14, 4096] (the model's default is 518), got " +
                     std::to_string(j.input_size));
  if (j.frames < 0) throw UsageError(frames_name(j) + " must be ≥ 0 (0 = all frames), got " + std::to_string(j.frames));
  if (j.max_res < 0)
    throw UsageError(option_name("DepthJob::max_res") + " must be ≥ 0 (0 = no limit), got " + std::to_string(j.max_res));
  VdaModel::inspect(j.model);  // the headers alone: another model's file is named now, not after the decode
}

// A cache entry worth using: what an estimate writes (f32 [N, H, W]), finite and not constant.
std::optional<std::string> entry_problem(const HostTensor& h) {
  if (h.dtype != DType::f32 || h.shape.size() != 3 || h.numel() == 0) return "not an f32 [N, H, W] array";
  const float* v = h.as<float>();
  for (int64_t i = 0; i < h.numel(); ++i)
    if (!std::isfinite(v[i])) return "holds NaN or Inf";
  for (int64_t i = 1; i < h.numel(); ++i)
    if (v[i] != v[0]) return std::nullopt;
  return "is constant";
}

// The estimate itself, in a Vulkan context of its own; the depth is returned, nothing is written.
HostTensor run_estimate(const DepthJob& job, const ProgressFn& progress, const CancelFn& cancelled, DepthSummary& s) {
  auto t = std::chrono::steady_clock::now();
  VideoInfo vi;
  const HostTensor frames = read_video_rgb8(job.video, job.frames, job.max_res, &vi);
  s.frames = int(frames.shape[0]), s.height = int(frames.shape[1]), s.width = int(frames.shape[2]);
  s.seconds_decode = seconds_since(t);
  if (cancelled && cancelled()) throw Cancelled();

  vk::ContextOptions copt;
  copt.device = job.device;
  copt.cache_dir = job.cache_dir;  // the pipeline cache beside the depth cache, as DVS_CACHE_DIR puts it
  vk::Context ctx(copt);
  FramesDepthOptions fo;
  fo.input_size = job.input_size;
  fo.input_size_option = input_size_name(job);
  fo.frames_option = frames_name(job);
  fo.model_file = job.model;
  fo.forecast_after_s = job.forecast_after_s;
  fo.notice = job.notice;
  check_vda_fits(ctx, VdaModel::inspect(job.model), s.height, s.width, fo);
  t = std::chrono::steady_clock::now();
  VdaModel model = VdaModel::load(ctx, job.model);
  if (job.metric) model.set_metric(*job.metric);
  s.model_size = model.config().name;
  s.metric = model.config().metric;
  s.weight_bytes = model.weight_bytes();
  s.seconds_load = seconds_since(t);
  if (cancelled && cancelled()) throw Cancelled();
  return estimate_frames_depth(model, frames, fo, progress, cancelled, s);
}

// What a cached estimate says of itself: sizes from the array, the rest from the checkpoint's headers.
DepthSummary summary_of_cached(const DepthJob& job, const HostTensor& depth) {
  DepthSummary s;
  s.frames = int(depth.shape[0]), s.height = int(depth.shape[1]), s.width = int(depth.shape[2]);
  VdaConfig cfg = VdaModel::inspect(job.model);
  if (job.metric) cfg.metric = *job.metric;
  s.model_size = cfg.name;
  s.metric = cfg.metric;
  const VdaInputSize in = vda_input_size(s.height, s.width, job.input_size, cfg.patch_size);
  s.input_height = int(in.height), s.input_width = int(in.width);
  s.windows = int(vda_window_frames(s.frames, cfg).size());
  s.from_cache = true;
  return s;
}

InversionCache depth_cache(const DepthJob& job) { return InversionCache(job.cache_dir, "depth"); }

}  // namespace

std::string depth_cache_key(const DepthJob& job) {
  // The estimate reads the video's bytes, the checkpoint's, the network input size, the frames kept, the
  // max-res scaling and the depth mode; not the device, the cache folder or how messages name the options.
  return InversionCache::key({"vda depth v1", file_fingerprint(job.video), file_fingerprint(job.model),
                              std::to_string(job.input_size), std::to_string(job.frames), std::to_string(job.max_res),
                              job.metric ? (*job.metric ? "metric" : "relative") : "checkpoint mode"});
}

std::string describe(const DepthSummary& s) {
  std::string line = "depth of " + count_text(s.frames, "frame", "frames") + " at " + std::to_string(s.height) + "x" +
                     std::to_string(s.width) + " (HxW) with " + s.model_size + (s.metric ? " (metric)" : "") +
                     ", network input " + std::to_string(s.input_height) + "x" + std::to_string(s.input_width) + ", " +
                     count_text(s.windows, "window", "windows");
  if (s.from_cache) return line + ": from the depth cache (" + s.cache_file.string() + ")";
  char rate[32];
  std::snprintf(rate, sizeof rate, "%.3g", s.frames / std::max(1e-9, s.seconds_depth));
  return line + ": decode " + duration_text(s.seconds_decode) + ", load " + duration_text(s.seconds_load) + ", depth " +
         duration_text(s.seconds_depth) + " (" + rate + " frames/s)";
}

bool depth_cache_has(const DepthJob& job) {
  return public_call("dvs::depth_cache_has", [&]() -> bool {
    if (job.refresh_cache) return false;
    return cache_entry_exists(depth_cache(job).file(depth_cache_key(job)));
  });
}

CachedDepth cached_depth(const DepthJob& job, const ProgressFn& progress, const CancelFn& cancelled) {
  return public_call("dvs::cached_depth", [&]() -> CachedDepth {
    check_job(job);
    refuse_old_cache_layout(job.cache_dir);  // an estimate can take a quarter of an hour: never silently again
    CachedDepth c;
    const InversionCache cache = depth_cache(job);
    c.key = depth_cache_key(job);
    c.file = cache.file(c.key);
    std::error_code ec;
    if (!job.refresh_cache && std::filesystem::exists(c.file, ec)) {
      const CacheEntryRead entry = read_cache_entry(c.file);
      std::optional<std::string> problem;
      if (!entry.problem.empty()) problem = entry.problem;
      else if (entry.tensor) problem = entry_problem(*entry.tensor);
      if (entry.tensor && !problem) {
        c.from_cache = true;
        c.summary = summary_of_cached(job, *entry.tensor);
        c.summary.cache_file = c.file;
        std::filesystem::last_write_time(c.file, std::filesystem::file_time_type::clock::now(), ec);  // recently used
        return c;
      }
      if (problem) {
        log_warning("the cached depth " + c.file.string() + " " + *problem + "; estimating it again");
        remove_cache_entry(c.file);
      }
    }
    // Where the estimate will be kept, checked before the work.
    if (auto p = file_write_problem(c.file, "give " + option_name("DepthJob::cache_dir") +
                                                " a writable folder or set DVS_CACHE_DIR to one"))
      throw Error("depth cache: " + *p);
    HostTensor depth;
    try {
      faults::set_stage("depth");
      crash_point("depth-estimate-begin");
      depth = run_estimate(job, progress, cancelled, c.summary);
      crash_point("depth-estimate-end");
    } catch (const vk::DeviceOutOfMemory& e) {  // the advice of this stage, not the CogVideoX run's
      throw Error("depth estimate: " + e.detail() + ". Try a smaller " + input_size_name(job) + " (the network input; " +
                      "default 518) or a smaller " + option_name("DepthJob::max_res") + " / fewer " + frames_name(job) +
                      in_words_of_caller("; dvs plan --depth-model " + job.model.filename().string(),
                                           "; dvs::plan_run_memory with MemoryPlanRequest::depth_model") +
                      " shows what the estimate needs",
                  ErrorKind::out_of_memory);
    } catch (const vk::DeviceLost& e) {
      throw Error(std::string("depth estimate: ") + e.what(), ErrorKind::device_lost);
    }
    faults::set_stage("depth-write");
    std::filesystem::create_directories(c.file.parent_path(), ec);
    write_cache_entry(c.file, depth);
    c.summary.cache_file = c.file;
    return c;
  });
}

DepthSummary estimate_depth(const DepthJob& job, const std::filesystem::path& out, const ProgressFn& progress,
                            const CancelFn& cancelled) {
  return public_call("dvs::estimate_depth", [&]() -> DepthSummary {
    check_job(job);
    const std::string ext = out.extension().string();
    if (ext != ".npz" && ext != ".npy") throw Error(out.string() + ": the depth file must end in .npz or .npy");
    if (auto p = file_write_problem(out, in_words_of_caller("give another --out", "give another output path"))) throw Error(*p);  // before the work, not after
    const CachedDepth c = cached_depth(job, progress, cancelled);
    try {
      const HostTensor depth = read_npy(c.file);
      std::error_code ec;
      std::filesystem::create_directories(std::filesystem::absolute(out).parent_path(), ec);
      crash_point("publish-before", out.filename().string());
      if (ext == ".npz") write_npz(out, {{"depths", depth}});
      else write_npy(out, depth);
      crash_point("publish-after", out.filename().string());
      remove_stale_temporaries(out);  // what a dvs depth killed while writing this file left
    } catch (const Error& e) {
      throw Error(std::string(e.what()) + "; the estimate is kept in the depth cache (" + c.file.string() +
                      "): the same command with a writable --out takes it from there",
                  e.kind());
    }
    return c.summary;
  });
}

}  // namespace dvs
