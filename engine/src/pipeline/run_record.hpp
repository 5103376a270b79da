// run.json: everything needed to understand or repeat a run — every setting actually used (the resolved preset
// values, intrinsics, tile size, the camera path's poses), absolute paths, the seed, the model's fingerprint,
// the LoRA, per-stage times, peak device and host memory, device and versions. `dvs run --from run.json` turns
// it back into the run's options (run_record_arguments).
#pragma once
#include <filesystem>
#include <array>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "dvs/pipeline.hpp"
#include "dvs/run_record.hpp"

namespace dvs {

struct RunRecordExtras {
  int steps = 0;
  double strength = 0;
  int inversion_steps = 0;
  double delta = 0;
  std::string negative_prompt;
  int t0 = 0, sampling_steps = 0;
  std::string device, driver, model_hash;
  bool slm_source_fell_back = false;
  std::string vulkan_api, opencv;  // the device's Vulkan API version, OpenCV's version
  bool dynamic_cfg = false;        // the resolved --dynamic-cfg (the preset's when not given)
  // What the run actually used where an option has a default worked out from the inputs.
  std::array<double, 4> intrinsics{};  // fx, fy, cx, cy in pixels of the working size
  int vae_tile_height = 0, vae_tile_width = 0;  // pixels, resolved (0 without tiling)
  std::vector<std::array<double, 16>> poses;    // the trajectory's per-frame 4×4 transforms, row-major
  std::string poses_hash;                       // hash of `poses`: compare two runs' camera paths at a glance
  std::string cache_dir;                        // the cache folder used (io/cache_root.hpp; --from's --cache-dir)
  std::string cache_problem;                    // why the cache asked for was not used (unwritable); empty if it was
  // The sampled latent in the cache: {"path", "key", "reused", "encoded_with"} (null without the cache).
  nlohmann::json latent;
  // --depth-model: where the depth came from (depth_source.hpp); null with --depth.
  nlohmann::json depth_estimate;
  // {"requested": "auto|resident|stream", "transformer": "resident|stream", "text_encoder": ...}: where the block
  // weights lived (job_stages.hpp, WeightResidencies::record).
  nlohmann::json weights;
};

// run_record_arguments (run.json back into `dvs run` arguments) is public, dvs/run_record.hpp; it is defined in
// run_record.cpp next to the writer so the two cannot drift apart.

void write_run_record(const std::filesystem::path& path, const RunOptions& o, const RunReport& r, const RunRecordExtras& x);

}  // namespace dvs
