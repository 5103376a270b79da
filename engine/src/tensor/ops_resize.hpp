// Bilinear resizing of image planes (Video-Depth-Anything's DPT head and its output upsampling:
// F.interpolate(mode="bilinear", align_corners=True), plus the half-pixel form for completeness).
#pragma once
#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops {

// x [..., H, W] -> y [..., Ho, Wo] (same leading dims, f32), PyTorch's CPU rule with the sizes given (not scale
// factors): align_corners: src = (in-1)/(out-1)·dst; else src = max(in/out·(dst + 0.5) - 0.5, 0). Planes or, when
// one plane exceeds a binding, output rows are walked in chunks within the limits in force. y must not alias x.
void resize_bilinear(vk::Recorder& rec, const Tensor& x, const Tensor& y, bool align_corners);

}  // namespace dvs::ops
