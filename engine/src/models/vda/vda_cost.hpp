// Arithmetic of a Video-Depth-Anything window (multiply-adds counted as 2 FLOPs), from the architecture and the
// sizes alone, layer by layer as vda_model.cpp runs them: what `dvs depth` multiplies by the device's measured
// rate to say, before a long estimate, how long it will take and what would make it cheaper.
#pragma once
#include <cstdint>

#include "spec/vda_config.hpp"

namespace dvs {

struct VdaFlops {
  double encoder_block = 0;  // one ViT block on one frame (all blocks cost the same)
  double encoder = 0;        // the whole encoder, every frame of the window (patch embedding included)
  double head = 0;           // the DPT head with its temporal modules, every frame of the window
  double window() const { return encoder + head; }
};

// frames: the window length (infer_len); input_h/w: the network input (multiples of the patch size).
VdaFlops vda_window_flops(const VdaConfig& cfg, int64_t frames, int64_t input_h, int64_t input_w);

}  // namespace dvs
