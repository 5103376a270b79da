// DINOv2's position-embedding resampling (interpolate_pos_encoding) for a grid of h x w patches, on the host in
// fp32 exactly as PyTorch computes it: the learned [1, 1 + M*M, D] table's M x M patch part, as a D-channel
// image, goes through bicubic interpolation (A = -0.75, align_corners False, no antialias) with the scale
// factors (h + offset)/M (rows) and (w + offset)/M (columns), source scale 1/s rounded to fp32, output size
// (h, w); the CLS row is kept. The only skip is h == w == M (the table as is). Small (at most 37 x 37 x D in,
// a few thousand rows out), once per grid, so it stays on the CPU.
#pragma once
#include <cstdint>

#include "io/host_tensor.hpp"

namespace dvs {

// table: f32 [1, 1 + M*M, D]; returns f32 [1 + h*w, D]. Throws dvs::Error on a table that is not square.
HostTensor vda_resample_pos_embed(const HostTensor& table, int64_t h, int64_t w, double interpolate_offset = 0.1);

}  // namespace dvs
