// Depth that reads fine but cannot be what it claims: negative disparity, and depth far smaller than the frame
// it must cover. Both are refused with the file named, where the value or size is and what to give instead.
#include <gtest/gtest.h>

#include <string>

#include "dvs/error.hpp"
#include "io/depth.hpp"
#include "support/expect_error.hpp"

namespace dvs {
namespace {

HostTensor ramp(int frames, int h, int w, float offset) {
  HostTensor t({frames, h, w}, DType::f32);
  for (int64_t i = 0; i < t.numel(); ++i) t.as<float>()[i] = float(i % 13) + offset;
  return t;
}

TEST(DepthLimits, NegativeDisparityIsRefusedWithItsPlace) {
  HostTensor d = ramp(2, 4, 5, 1.0f);
  EXPECT_NO_THROW(depth_from_array(d, "ok.npy"));
  d.as<float>()[20 + 2 * 5 + 3] = -0.5f;  // frame 1, row 2, column 3
  d.as<float>()[20 + 3 * 5 + 4] = -0.25f;
  test::expect_error([&] { depth_from_array(d, "disp.npy"); },
                     {"disp.npy: disparity (inverse depth) cannot be negative, but frame 1 holds -0.500000 at row 2, "
                      "column 3 (2 of 40 values are below 0", "RenderJob::metric_depth"});
  // Zero is a valid disparity (infinitely far, clipped to the far plane), and metric depth has its own rule.
  d.as<float>()[20 + 2 * 5 + 3] = 0.0f;
  d.as<float>()[20 + 3 * 5 + 4] = 0.0f;
  EXPECT_NO_THROW(depth_from_array(d, "zero.npy"));
}

// The rule: the part of the depth that covers the video's frame needs at least 1/8 of its rows and columns, counted
// in the video's own pixels (not the working size, which may upscale both).
TEST(DepthLimits, DepthFarSmallerThanTheFrameIsRefused) {
  const HostTensor tiny = ramp(1, 4, 7, 1.0f);
  const VideoFrameGeometry clip{384, 672, 384, 672, ResizeMode::crop};
  test::expect_error([&] { map_depth_to_video(tiny, 1, clip, DepthFit::error, false, "tiny.npy"); },
                     {"tiny.npy: the depth frames are 4x7 (HxW), far too small for the video's 384x672 frames",
                      "each depth pixel would cover 96 video pixels a side (at most 8"});
  // 48x84 is exactly 1/8: accepted; one row fewer is not.
  EXPECT_EQ(map_depth_to_video(ramp(1, 48, 84, 1.0f), 1, clip, DepthFit::error, false, "d.npy").shape,
            (Shape{1, 384, 672}));
  EXPECT_THROW(map_depth_to_video(ramp(1, 47, 84, 1.0f), 1, clip, DepthFit::stretch, false, "d.npy"), Error);
  // Depth at the video's own size always passes, however far --size upscales both (a 48x64 clip at 480x720).
  const VideoFrameGeometry small_clip{48, 64, 480, 720, ResizeMode::crop};
  EXPECT_EQ(map_depth_to_video(ramp(1, 48, 64, 1.0f), 1, small_clip, DepthFit::error, false, "d.npy").shape,
            (Shape{1, 480, 720}));
  EXPECT_THROW(map_depth_to_video(ramp(1, 5, 7, 1.0f), 1, small_clip, DepthFit::error, false, "d.npy"), Error);
  // The size counted is the part that covers the video's kept frame: a centre crop of the video to a square keeps
  // 384 of 672 source columns, so 48 depth columns are left of 84, still 1/8 of the 384 working columns.
  const VideoFrameGeometry square{384, 672, 384, 384, ResizeMode::crop};
  EXPECT_NO_THROW(map_depth_to_video(ramp(1, 48, 84, 1.0f), 1, square, DepthFit::error, false, "d.npy"));
  EXPECT_THROW(map_depth_to_video(ramp(1, 40, 70, 1.0f), 1, square, DepthFit::error, false, "d.npy"), Error);
}

}  // namespace
}  // namespace dvs
