// Device memory of a Video-Depth-Anything window, from the architecture and the sizes alone (for `dvs plan` and
// the run's preflight): the weights as VdaModel uploads them, and the largest live set of one window's forward
// plus its upsampling to the frame size, phase by phase as vda_model.cpp allocates and frees.
#pragma once
#include <cstdint>
#include <optional>
#include <string>

#include "spec/vda_config.hpp"

namespace dvs {

struct VdaMemory {
  uint64_t weights = 0;      // bytes resident while the model is loaded
  uint64_t activations = 0;  // the largest phase's live tensors above the weights
  std::string peak_phase;    // which phase that is
  uint64_t largest_tensor = 0;
  std::string largest_what;
  uint64_t total() const { return weights + activations; }
};

// frames: the window length (infer_len); input_h/w: the network input (multiples of the patch size);
// frame_h/w: the clip's frames (the upsampled window); micro_batch as VdaModel::set_micro_batch.
VdaMemory plan_vda_memory(const VdaConfig& cfg, int64_t frames, int64_t input_h, int64_t input_w, int64_t frame_h,
                          int64_t frame_w, int micro_batch, uint64_t alignment = 256);

// Whether a whole estimate of frames frame_h x frame_w at network input `input_size` fits: each tensor one
// allocation of at most `alloc` bytes (maxMemoryAllocationSize, 0 = no limit), weights + largest phase within
// `budget` when given. "" when it fits; else what is over, named as the depth estimate, and what helps: the largest
// smaller multiple of 14 that fits, given as `input_size_option` (--input-size for dvs depth, --depth-input-size
// for run/render/plan). `limit_source` names the device in the message. dvs plan, run's preflight and dvs depth
// all ask this.
std::string vda_fit_problem(const VdaConfig& cfg, int64_t frame_h, int64_t frame_w, int input_size, uint64_t alloc,
                            std::optional<uint64_t> budget, uint64_t alignment, const std::string& limit_source,
                            const std::string& input_size_option);

}  // namespace dvs
