#include "dvs/depth_estimate.hpp"

#include <chrono>

#include "dvs/error.hpp"
#include "io/npy.hpp"
#include "io/npz_writer.hpp"
#include "io/video.hpp"
#include "models/vda/vda_model.hpp"
#include "models/vda/vda_video.hpp"
#include "pipeline/inversion_cache.hpp"
#include "vk/context.hpp"
#include "vk/memory.hpp"

namespace dvs {
namespace {

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

void check_job(const DepthJob& j) {
  if (!std::filesystem::is_regular_file(j.video)) throw Error(j.video.string() + ": no such video file (give --video FILE)");
  if (!std::filesystem::is_regular_file(j.model))
    throw Error(j.model.string() + ": no such depth model (give --depth-model video_depth_anything_vits.pth; README.md "
                "says where the checkpoints are)");
  if (j.input_size < 14 || j.input_size > 4096)
    throw Error("--input-size must be in [14, 4096] (the model's default is 518), got " + std::to_string(j.input_size));
  if (j.frames < 0) throw Error("--frames must be ≥ 0 (0 = all frames)");
  if (j.max_res < 0) throw Error("--max-res must be ≥ 0 (0 = no limit)");
}

}  // namespace

DepthSummary estimate_depth(const DepthJob& job, const std::filesystem::path& out, const ProgressFn& progress,
                            const CancelFn& cancelled) {
  check_job(job);
  const std::string ext = out.extension().string();
  if (ext != ".npz" && ext != ".npy") throw Error(out.string() + ": the depth file must end in .npz or .npy");
  DepthSummary s;
  auto t = std::chrono::steady_clock::now();
  VideoInfo vi;
  const HostTensor frames = read_video_rgb8(job.video, job.frames, job.max_res, &vi);
  s.frames = int(frames.shape[0]), s.height = int(frames.shape[1]), s.width = int(frames.shape[2]);
  s.seconds_decode = seconds_since(t);

  vk::ContextOptions copt;
  copt.device = job.device;
  vk::Context ctx(copt);
  t = std::chrono::steady_clock::now();
  VdaModel model = VdaModel::load(ctx, job.model);
  if (job.metric) model.set_metric(*job.metric);
  s.model_size = model.config().name;
  s.metric = model.config().metric;
  s.weight_bytes = model.weight_bytes();
  s.seconds_load = seconds_since(t);

  t = std::chrono::steady_clock::now();
  VdaVideoOptions o;
  o.input_size = job.input_size;
  o.on_window = [&](int done, int total) {
    s.windows = total;
    if (progress) progress("depth", done, total, "");
    if (cancelled && cancelled()) throw Cancelled();
  };
  const VdaVideoResult r = vda_video_depth(model, frames, o);
  s.input_height = int(r.input.height), s.input_width = int(r.input.width);
  s.seconds_depth = seconds_since(t);
  s.peak_device_bytes = ctx.allocator().stats().peak_bytes_reserved;
  if (ext == ".npz") write_npz(out, {{"depths", r.depth}});
  else write_npy(out, r.depth);
  return s;
}

CachedDepth cached_depth(const DepthJob& job, const std::filesystem::path& cache_dir, bool refresh,
                         const ProgressFn& progress, const CancelFn& cancelled) {
  check_job(job);
  CachedDepth c;
  const InversionCache cache(cache_dir, "depth");
  c.key = InversionCache::key({"vda depth v1", file_fingerprint(job.video), file_fingerprint(job.model),
                               std::to_string(job.input_size), std::to_string(job.frames), std::to_string(job.max_res),
                               job.metric ? (*job.metric ? "metric" : "relative") : "checkpoint mode"});
  c.file = cache.file(c.key);
  std::error_code ec;
  if (!refresh && std::filesystem::is_regular_file(c.file, ec)) {
    try {
      const HostTensor h = read_npy(c.file);
      if (h.dtype == DType::f32 && h.shape.size() == 3 && h.numel() > 0) {
        c.from_cache = true;
        return c;
      }
    } catch (const Error&) {
    }
    std::filesystem::remove(c.file, ec);  // damaged: estimate again
  }
  std::filesystem::create_directories(c.file.parent_path(), ec);
  c.summary = estimate_depth(job, c.file, progress, cancelled);
  return c;
}

}  // namespace dvs
