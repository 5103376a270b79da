// Per-device kernel choices (tile shapes, register blocking) of the GEMM-shaped shaders, kept in one table
// (kernel_tuning.cpp) so that op files hold no device-type checks and a new device's variant is a table
// entry. Today it serves the convolutions (shaders/nn/conv_gemm.glsl).
#pragma once
#include <cstdint>
#include <string>

#include "tensor/tensor.hpp"
#include "vk/device_info.hpp"

namespace dvs::ops {

// Register blocking of conv_gemm: a cluster of 8 lanes computes `rows` output pixels x 8*`cols` output
// channels; `sg_m` of the workgroup's 8 clusters lie along the pixels. `lanes`: 0 subgroups of exactly 8,
// 1 clusters of 8 inside wider subgroups, 2 no subgroup shuffles (every lane fetches every pixel).
// `k_unroll`: 8-channel steps per trip of the channel loop (at most; 1, 2 or 4, as the channels allow).
struct GemmTile {
  int rows = 8, cols = 3, sg_m = 2, lanes = 0, k_unroll = 1;
};

// The tile for a convolution with `outputs` output pixels, `out_channels` output channels and weights
// stored as `wdt`, on the device described by `caps`. `device_class` (optional) receives the name of the
// table entry used.
GemmTile conv_tile(const vk::DeviceCaps& caps, DType wdt, int64_t outputs, int64_t out_channels,
                   std::string* device_class = nullptr);

// How the lanes of a cluster talk on this device (GemmTile::lanes): a property of its subgroups.
int gemm_lanes(const vk::DeviceCaps& caps);

// Output pixels of one row that one invocation of the convolution's input repack (conv_pack_input.comp)
// writes; 0: the whole row segment of the chunk.
int conv_pack_columns(const vk::DeviceCaps& caps);

}  // namespace dvs::ops
