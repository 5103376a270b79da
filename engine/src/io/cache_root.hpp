// The cache folder: one meaning for `--cache-dir DIR`, `DVS_CACHE_DIR=DIR` and the library's `cache_dir` (RunOptions,
// DepthJob, RenderJob::depth_cache_dir, dvs_pipeline_options). DIR holds the Vulkan pipeline cache
// (pipelines-<vendor>-<device>.bin) and, in DIR/inversions, the run caches' entries (depth estimates, inversions,
// sampled latents: pipeline/inversion_cache.hpp). Before, --cache-dir named the entries' folder itself while the
// variable named the folder above it; the entries such a --cache-dir left directly in DIR are found by
// old_cache_layout (pipeline/inversion_cache.hpp) and named, never silently computed again.
#pragma once
#include <filesystem>

namespace dvs {

// `given` when not empty, else $DVS_CACHE_DIR, else ~/.cache/dvs (without HOME: <temp>/dvs-cache).
std::filesystem::path cache_root(const std::filesystem::path& given = {});

// The folder of the run caches' entries in the cache folder `root`.
inline std::filesystem::path cache_entries_folder(const std::filesystem::path& root) { return root / "inversions"; }

}  // namespace dvs
