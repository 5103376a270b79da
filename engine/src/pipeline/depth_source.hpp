// `--depth-model` for run, invert and render: the clip's depth estimated with Video-Depth-Anything (or taken from
// the depth cache, keyed by the video's bytes, the model file and the settings) in a Vulkan context of its own
// that is gone before the diffusion models load; the job then reads the cached file as if given with --depth.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>

#include "dvs/pipeline.hpp"

#include "dvs/depth_estimate.hpp"

namespace dvs {

// The depth estimate a job with --depth-model asks for (the cache key's inputs, the cache, the option names).
DepthJob depth_job_for(const RenderJob& job, const std::filesystem::path& cache_dir, bool refresh);

// The depth cache's key (defined in depth_estimate.cpp): a hash of everything the estimate depends on.
std::string depth_cache_key(const DepthJob& job);

// Nothing when job.depth_model is empty. Otherwise sets job.depth to the estimate and returns its provenance
// for run.json: {"model", "input_size", "file", "key", "from_cache", "seconds"}.
nlohmann::json resolve_depth_model(RenderJob& job, const std::filesystem::path& cache_dir, bool refresh,
                                   const ProgressFn& progress, const CancelFn& cancelled);

}  // namespace dvs
