// Reductions with a two-level scheme (per-block partials, then a per-segment merge) so long sums keep
// fp32 accuracy: per-channel mean and population variance (AdaIN statistics), whole-tensor sum and max.
// The partials need a caller-provided f32 scratch tensor of reduce_scratch_elems() elements (callers
// allocate it with the rest of their activations; a recording keeps using it on every replay).
#pragma once
#include <cstdint>

#include "tensor/dispatch.hpp"
#include "vk/device_info.hpp"

namespace dvs::ops {

// A family of equal-length reductions: element j of segment s is at
// s*seg_stride + (j / inner)*outer_stride + (j % inner), j in [0, seg_len).
struct Segments {
  int64_t count = 1, seg_len = 0, inner = 0, seg_stride = 0, outer_stride = 0;
};

enum class ReduceMode : uint32_t { sum = 0, max = 1, mean_var = 2 };

// f32 elements of scratch the reductions of `segs` need. Under limits too small to bind one block of
// partials (bindings of a few KiB, DVS_LIMITS) blocks shrink and more scratch is needed: the caps overload
// sizes for the limits in force, the others for ordinary device limits.
int64_t reduce_scratch_elems(const Segments& segs);
int64_t reduce_scratch_elems(int64_t segments, int64_t seg_len);
int64_t reduce_scratch_elems(const vk::DeviceCaps& caps, const Segments& segs);

// Records both levels: out0[out_offset + s] = sum / max / mean of segment s; out1[out_offset + s] =
// population variance (mean_var only; out1 may be out0's tensor otherwise). x, out0, out1, scratch f32.
void reduce_segments(vk::Recorder& rec, const Tensor& x, const Segments& segs, ReduceMode mode, const Tensor& out0,
                     const Tensor& out1, const Tensor& scratch, int64_t out_offset = 0);

// The segments of channel_mean_var (for sizing its scratch).
Segments channel_segments(int64_t outer, int64_t channels, int64_t inner);

// x viewed as [outer, C, inner] (e.g. latents [F, C, H, W]: outer = F, inner = H*W): mean [C] and population
// variance [C] over (outer, inner).
void channel_mean_var(vk::Recorder& rec, const Tensor& x, int64_t outer, int64_t channels, int64_t inner,
                      const Tensor& mean, const Tensor& var, const Tensor& scratch);

// out [1] = sum / max of all elements of x.
void sum_all(vk::Recorder& rec, const Tensor& x, const Tensor& out, const Tensor& scratch);
void max_all(vk::Recorder& rec, const Tensor& x, const Tensor& out, const Tensor& scratch);

}  // namespace dvs::ops
