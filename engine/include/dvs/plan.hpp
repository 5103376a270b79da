// The device memory a whole run needs, planned from the model's config.json files alone (no weights read, no
// device opened): weight bytes per component, the peak of each model call, the peak of the run and, given a
// budget or device limits, the VAE spatial tiling that fits. What `dvs plan` prints.
#pragma once
#include <cstdint>
#include <optional>
#include <string>

#include "dvs/devices.hpp"
#include "dvs/api.hpp"

namespace dvs {

struct MemoryPlanRequest {
  std::string model;                   // a model folder laid out like THUDM/CogVideoX-5b-I2V, or a built-in name
  int64_t frames = 49, height = 480, width = 720;  // the clip, pixels
  std::optional<uint64_t> budget;      // device memory available, bytes; unset: the limits' memory (if any)
  uint64_t alignment = 256;            // the allocator's; raised to the limits' alignment
  std::optional<DeviceLimits> limits;  // checked when given: a setting runs only within them
  // Include the depth estimate of `dvs run --depth-model` (it runs first, alone): a checkpoint (only its
  // tensor list is read) or a released size "vits", "vitb", "vitl". Empty: no depth estimate.
  std::string depth_model;
  int depth_input_size = 518;
  int64_t depth_frame_height = 0, depth_frame_width = 0;  // the video's frames; 0 = the clip size
  // The transformer's and T5's block weights (dvs run --weights): "auto" (streamed only where resident does not
  // fit the budget), "resident" or "stream". The plan prints what streaming costs either way.
  std::string weights = "auto";
  double upload_bytes_per_second = 0;  // host -> device rate for the upload times (0: the limits' figure, if any)
};

struct MemoryPlanReport {
  bool checked = false;      // a budget or limits were given
  bool runs = true;          // some setting runs within them (always true when not checked)
  uint64_t weights_bytes = 0, run_peak_bytes = 0;  // untiled
  std::string table;         // the human-readable plan, as `dvs plan` prints it
  std::string json;          // the same as one JSON object (`dvs plan --json`), indented
};

// Throws dvs::UsageError when the request does not fit the model (frames not 4k+1, a size that is not a
// multiple of the model's latent cell, an alignment that is not a power of two), dvs::Error naming the file
// when the model or the depth checkpoint cannot be read.
DVS_API MemoryPlanReport plan_run_memory(const MemoryPlanRequest& request);

// The built-in model configurations ("cogvideox-5b-i2v": the real configuration, bf16 weights).
DVS_API bool is_builtin_model(const std::string& name);

// "24GiB", "80GB", "1.5 GiB", "512MiB", "1000000" (bytes). Throws dvs::UsageError naming `option` otherwise.
DVS_API uint64_t parse_byte_size(const std::string& text, const std::string& option);

}  // namespace dvs
