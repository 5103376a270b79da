// Video-Depth-Anything's long-video bookkeeping, exact to infer_video_depth: which clip frame each window position
// holds (windows of infer_len frames every infer_len - overlap, the clip padded with copies of its last frame, the
// first `overlap` positions of later windows taken from the previous window's key frames), and the stitching of
// the windows' disparities (least-squares scale/shift on the key frames, linear blending over interp_len frames,
// clamping at 0) in float32 as numpy does it.
#pragma once
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "io/host_tensor.hpp"
#include "spec/vda_config.hpp"

namespace dvs {

// Clip frame index at every position of every window, for a clip of `frames` frames. Throws dvs::Error when the
// config's inference constants are inconsistent (keyframes must number `overlap`, 2 <= interp_len < overlap).
std::vector<std::vector<int64_t>> vda_window_frames(int64_t frames, const VdaConfig& cfg);

// compute_scale_and_shift with an all-ones mask: the 2x2 normal equations from float32 pairwise sums (numpy's
// np.sum), solved in float32; (1, 0) when the system is singular.
std::array<float, 2> vda_scale_shift(std::span<const float> prediction, std::span<const float> target);

// numpy's float32 np.sum of a contiguous array (pairwise summation, 8 accumulators, blocks of 128).
float numpy_pairwise_sum(std::span<const float> v);

// Consumes the windows' disparities in order (each [infer_len][H*W] at the frame resolution) and builds the
// aligned clip.
class VdaStitcher {
 public:
  VdaStitcher(const VdaConfig& cfg, int64_t frame_pixels);
  void add_window(std::vector<std::vector<float>> window);
  // (scale, shift) applied to each window after the first.
  const std::vector<std::array<float, 2>>& scale_shift() const { return scale_shift_; }
  // The first `frames` aligned frames as f32 [frames, H, W].
  HostTensor finish(int64_t frames, int64_t height, int64_t width) const;

 private:
  const VdaConfig& cfg_;
  int64_t pixels_;
  std::vector<std::vector<float>> aligned_, reference_;
  std::vector<std::array<float, 2>> scale_shift_;
};

}  // namespace dvs
