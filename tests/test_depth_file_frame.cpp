// dvs::load_depth_frame (dvs/depth_file.hpp): one frame of a clip's depth (a file, or in memory) as dvs render
// takes it. Expected values from the official conversion written out here (dn over the WHOLE clip, z = 10000 / max(3900·dn, 1e-5)).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "dvs/depth_file.hpp"
#include "io/npy.hpp"
#include "support/expect_error.hpp"
#include "support/files.hpp"

namespace {

// Disparity [3,H,W]: frame f pixel i = 1 + i + 10·f², so the clip's range spans frames 0..2 and no frame is its own.
dvs::HostTensor clip_disparity(int H, int W) {
  dvs::HostTensor t({3, H, W}, dvs::DType::f32);
  for (int f = 0; f < 3; ++f)
    for (int i = 0; i < H * W; ++i) t.as<float>()[f * H * W + i] = float(1 + i + 10 * f * f);
  return t;
}

float official_depth(float d, float lo, float hi) {
  const float dn = (d - lo) / (hi - lo);
  return std::clamp(10000.0f / std::max(3900.0f * dn, 1e-5f), 1e-4f, 1e4f);
}

TEST(DepthFileFrame, DisparityIsConvertedOverTheWholeClip) {
  dvs::test::TempDir dir;
  const int H = 4, W = 6;
  const dvs::HostTensor disparity = clip_disparity(H, W);
  dvs::write_npy(dir / "depth.npy", disparity);
  const float lo = 1, hi = float(H * W + 40);  // frame 0's first pixel, frame 2's last
  const dvs::DepthFrame d = dvs::load_depth_frame(dir / "depth.npy", 1, H, W);
  ASSERT_EQ(d.height, H);
  ASSERT_EQ(d.width, W);
  EXPECT_EQ(d.frames_in_file, 3);
  for (int i = 0; i < H * W; ++i) {
    const float want = official_depth(disparity.as<float>()[H * W + i], lo, hi);
    EXPECT_NEAR(d.depth[size_t(i)], want, 1e-6f * want) << "pixel " << i;
  }
}

TEST(DepthFileFrame, DepthOfTheVideosSizeIsCentreCroppedLikeTheVideo) {
  // The video (and its depth) 8x16, the working size 8x8: the crop keeps columns 4..11 at scale 1.
  dvs::test::TempDir dir;
  const int H = 8, W = 16;
  const dvs::HostTensor disparity = clip_disparity(H, W);
  dvs::write_npy(dir / "depth.npy", disparity);
  dvs::DepthFileOptions o;
  o.source_height = H;
  o.source_width = W;
  const dvs::DepthFrame d = dvs::load_depth_frame(dir / "depth.npy", 2, 8, 8, o);
  const float lo = 1, hi = float(H * W + 40);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) {
      const float want = official_depth(disparity.as<float>()[2 * H * W + y * W + x + 4], lo, hi);
      EXPECT_NEAR(d.depth[size_t(y * 8 + x)], want, 1e-6f * want) << "row " << y << ", column " << x;
    }
}

TEST(DepthFileFrame, MetricDepthIsTakenAsItIs) {
  dvs::test::TempDir dir;
  const dvs::HostTensor depth = clip_disparity(4, 6);
  dvs::write_npy(dir / "depth.npy", depth);
  dvs::DepthFileOptions o;
  o.metric_depth = true;
  const dvs::DepthFrame d = dvs::load_depth_frame(dir / "depth.npy", 2, 4, 6, o);
  for (int i = 0; i < 24; ++i) EXPECT_EQ(d.depth[size_t(i)], float(1 + i + 40));
}

TEST(DepthFileFrame, ErrorsNameTheFile) {
  dvs::test::TempDir dir;
  dvs::write_npy(dir / "depth.npy", clip_disparity(4, 6));
  const std::string file = (dir / "depth.npy").string();
  dvs::test::expect_error([&] { dvs::load_depth_frame(dir / "depth.npy", 3, 4, 6); }, file, "holds 3 frame(s)");
  dvs::test::expect_error([&] { dvs::load_depth_frame(dir / "missing.npz", 0, 4, 6); }, (dir / "missing.npz").string(),
                          "no such depth file");
  dvs::DepthFileOptions o;
  o.depth_fit = "sideways";
  EXPECT_THROW(dvs::load_depth_frame(dir / "depth.npy", 0, 4, 6, o), dvs::Error);
}

// The clip's disparity in memory (what DepthEstimator writes): converted over the whole clip and centre-cropped
// from the video's size like the file form, so `--depth-model` frames equal `--depth` frames.
TEST(DepthFileFrame, ClipInMemoryIsConvertedAndMappedAsAFileIs) {
  const int H = 8, W = 16;
  dvs::HostTensor disparity = clip_disparity(H, W);
  const dvs::HostView clip{disparity.as<float>(), dvs::ElementType::f32, {3, H, W}};
  dvs::DepthFileOptions o;
  o.source_height = H;
  o.source_width = W;
  const dvs::DepthFrame d = dvs::load_depth_frame(clip, 2, 8, 8, o);
  EXPECT_EQ(d.frames_in_file, 3);
  const float lo = 1, hi = float(H * W + 40);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) {
      const float want = official_depth(disparity.as<float>()[2 * H * W + y * W + x + 4], lo, hi);
      EXPECT_NEAR(d.depth[size_t(y * 8 + x)], want, 1e-6f * want) << "row " << y << ", column " << x;
    }
}

TEST(DepthFileFrame, ClipInMemoryErrorsSayWhatIsWrong) {
  dvs::HostTensor disparity = clip_disparity(4, 6);
  const dvs::HostView clip{disparity.as<float>(), dvs::ElementType::f32, {3, 4, 6}};
  dvs::test::expect_error([&] { dvs::load_depth_frame(clip, 3, 4, 6); }, "depth in memory", "holds 3 frame(s)");
  const dvs::HostView flat{disparity.as<float>(), dvs::ElementType::f32, {3 * 4, 6}};
  dvs::test::expect_error([&] { dvs::load_depth_frame(flat, 0, 4, 6); }, "depth in memory", "f32 [F,H,W]");
  const dvs::HostView bytes{disparity.as<float>(), dvs::ElementType::u8, {3, 4, 6}};
  dvs::test::expect_error([&] { dvs::load_depth_frame(bytes, 0, 4, 6); }, "depth in memory", "f32 [F,H,W]");
}

}  // namespace
