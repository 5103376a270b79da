// Spatial tiling of the CogVideoX VAE, as diffusers' tiled_encode / tiled_decode: overlapping tiles, each run
// through the (frame-batched) model separately, then blended on the host with linear ramps (blend_v on the
// tile above, blend_h on the tile to the left, in place and in row-major tile order) and cropped.
#pragma once
#include <cstdint>
#include <functional>

#include "io/host_tensor.hpp"
#include "spec/cogvideox_config.hpp"

namespace dvs::models {

using dvs::VaeConfig;  // spec/cogvideox_config.hpp
struct VaeTiling;

struct TilePlan {
  int64_t tile_in_h = 0, tile_in_w = 0;    // input tile size (pixels for encode, latents for decode)
  int64_t stride_h = 0, stride_w = 0;      // distance between tile origins in the input
  int64_t blend_h = 0, blend_w = 0;        // blend extent in the output
  int64_t limit_h = 0, limit_w = 0;        // rows / columns of each blended output tile kept

  static TilePlan for_encode(const VaeConfig& cfg, const VaeTiling& tiling);
  static TilePlan for_decode(const VaeConfig& cfg, const VaeTiling& tiling);
};

// in: f32 [B, C, F, H, W]; run(tile) maps an input tile to its output tile (f32, 5-D).
HostTensor run_tiled(const TilePlan& plan, const HostTensor& in, const std::function<HostTensor(const HostTensor&)>& run);

// diffusers' blend_v / blend_h: b's first rows (columns) become a ramp from a's last ones. In place on b.
void blend_rows(const HostTensor& a, HostTensor& b, int64_t extent);
void blend_cols(const HostTensor& a, HostTensor& b, int64_t extent);

}  // namespace dvs::models
