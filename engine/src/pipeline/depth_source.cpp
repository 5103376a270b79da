#include "pipeline/depth_source.hpp"

#include <chrono>

#include "dvs/depth_estimate.hpp"
#include "models/vda/vda_model.hpp"
#include "io/option_names.hpp"

namespace dvs {

DepthJob depth_job_for(const RenderJob& job, const std::filesystem::path& cache_dir, bool refresh) {
  DepthJob d;
  d.video = job.video;
  d.model = job.depth_model;
  d.input_size = job.depth_input_size;
  d.frames = job.frames;  // the frames the job uses (0 = all)
  d.device = job.device;
  d.cache_dir = cache_dir;
  d.refresh_cache = refresh;
  d.input_size_option = option_name("RenderJob::depth_input_size");
  return d;
}

nlohmann::json resolve_depth_model(RenderJob& job, const std::filesystem::path& cache_dir, bool refresh,
                                   const ProgressFn& progress, const CancelFn& cancelled) {
  if (job.depth_model.empty()) return nullptr;
  const auto t = std::chrono::steady_clock::now();
  const DepthJob d = depth_job_for(job, cache_dir, refresh);
  const CachedDepth c = cached_depth(d, progress, cancelled);
  job.depth = c.file;
  job.metric_depth = VdaModel::inspect(job.depth_model).metric;  // metric checkpoints give depth, others disparity
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
  nlohmann::json j = {{"model", std::filesystem::absolute(job.depth_model).lexically_normal().string()},
                      {"input_size", job.depth_input_size},
                      {"max_res", d.max_res},
                      {"file", c.file.string()},
                      {"key", c.key},
                      {"from_cache", c.from_cache},
                      {"seconds", seconds}};
  if (!c.from_cache)
    j["estimate"] = {{"model_size", c.summary.model_size}, {"metric", c.summary.metric},
                     {"frames", c.summary.frames}, {"height", c.summary.height}, {"width", c.summary.width},
                     {"network_input", {c.summary.input_height, c.summary.input_width}},
                     {"windows", c.summary.windows}, {"peak_device_bytes", c.summary.peak_device_bytes}};
  return j;
}

}  // namespace dvs
