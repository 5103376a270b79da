// run.json: everything needed to understand or repeat a run — every setting (the resolved preset values),
// the seed, the model's fingerprint, the LoRA, per-stage times, peak device and host memory, device and versions.
#pragma once
#include <filesystem>
#include <string>

#include "dvs/pipeline.hpp"

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
};

void write_run_record(const std::filesystem::path& path, const RunOptions& o, const RunReport& r, const RunRecordExtras& x);

}  // namespace dvs
