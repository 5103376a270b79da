// A random-weight Video-Depth-Anything checkpoint of any architecture (a released size or a config): every tensor
// the released checkpoints hold, under their names and shapes, drawn like the conformance pack's models (so every
// path matters: LayerScale gammas around 0.5, a last bias that keeps most disparities above the final ReLU), and
// the temporal position tables as the class computes them. For measurements at the real size without downloads.
#pragma once
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "io/host_tensor.hpp"
#include "spec/vda_config.hpp"

namespace dvs {

// Names and shapes of every tensor of a checkpoint of this architecture, in the released files' order.
std::vector<std::pair<std::string, Shape>> vda_checkpoint_schema(const VdaConfig& cfg);

// The schema filled with seeded random f32 values.
std::vector<std::pair<std::string, HostTensor>> vda_random_checkpoint(const VdaConfig& cfg, uint64_t seed);

}  // namespace dvs
