// The identity pose gives back the input at every size (issue 34 §2 item 8): the soft splat of a random frame with
// disparity 0.5 + y/H (the far rows first, as in a landscape) at the intrinsics dvs uses, swept over many image
// sizes (odd ones too), must equal the input, the mask all visible. Before, row 0 or column 0 came back up to 210
// levels off at 131 of 320 sizes up to 128×160 while the mask said visible; the hard splat was exact.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "geometry/splat.hpp"
#include "io/depth.hpp"
#include "support/gpu.hpp"

namespace dvs::geometry {
namespace {

using test::GpuTest;

struct Frame {
  HostTensor rgb, depth;
};

// A random frame in [−1, 1] and its depth from disparity 0.5 + y/H, converted as dvs render converts a depth
// file's disparity (io/depth.hpp: row 0, the smallest disparity, becomes the far clip, 10^4; the rows below
// 10^4 / (3900 · y/(H−1)): a sky above nearer ground); `metric`: depth 1 / (0.5 + y/H) instead, no far clip.
Frame landscape(int H, int W, uint32_t seed, bool metric) {
  std::mt19937 g(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  Frame f{HostTensor({1, 3, H, W}, DType::f32), HostTensor({1, H, W}, DType::f32)};
  for (int64_t i = 0; i < f.rgb.numel(); ++i) f.rgb.as<float>()[i] = u(g);
  HostTensor disparity({1, H, W}, DType::f32);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      disparity.as<float>()[y * W + x] = 0.5f + float(y) / float(H);
      f.depth.as<float>()[y * W + x] = 1.f / (0.5f + float(y) / float(H));
    }
  if (!metric && H > 1) f.depth = depth_from_array(disparity, "disparity 0.5 + y/H", DepthOptions{});
  return f;
}

struct Worst {
  double levels = 0;  // largest difference from the input, in 8-bit levels (255 for the range [−1, 1])
  int x = -1, y = -1, hidden = 0;
};

Worst against_input(const RenderedClip& r, const Frame& f, int H, int W) {
  Worst w;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      if (r.mask.as<float>()[y * W + x] != 1.f) ++w.hidden;
      for (int c = 0; c < 3; ++c) {
        const size_t i = (size_t(c) * H + y) * W + x;
        const double d = std::abs(double(r.render.as<float>()[i]) - double(f.rgb.as<float>()[i])) * 127.5;
        if (d > w.levels) w = {d, x, y, w.hidden};
      }
    }
  return w;
}

// Every multiple of 8 up to 128×160 (the 320 sizes) and odd and small sizes, at dvs render's default
// intrinsics (square pixels, f = 500 at 1024×576 scaled to cover) and the official per-axis ones.
TEST_F(GpuTest, GeometrySplatIdentityGivesBackTheInputAtEverySize) {
  std::vector<std::pair<int, int>> sizes;
  for (int H = 8; H <= 128; H += 8)
    for (int W = 8; W <= 160; W += 8) sizes.push_back({H, W});
  for (std::pair<int, int> s : std::vector<std::pair<int, int>>{{1, 1}, {1, 7}, {5, 1}, {3, 3}, {7, 13}, {13, 7}, {17, 31},
                                                                {31, 45}, {45, 80}, {48, 81}, {49, 80}, {97, 161}, {101, 99},
                                                                {127, 159}, {129, 131}, {96, 160}, {480, 720}, {479, 721}})
    sizes.push_back(s);
  int failed = 0, rendered = 0;
  std::string first;
  // Under forced limits (DVS_LIMITS binding=64KiB, groups=64) the renderer refuses the larger frames, as it should
  // (one frame's accumulation is one binding and one dispatch): those sizes are left out there, and only there.
  const bool forced = ctx().caps().forced_limits.any();
  for (const auto& [H, W] : sizes) {
    ++rendered;
    for (bool squash : {false, true}) {
      // The disparity's conversion with dvs render's intrinsics; metric depth with the official per-axis ones.
      const Frame f = landscape(H, W, uint32_t(H * 1000 + W), squash);
      const Intrinsics K = squash ? Intrinsics::official_default(W, H) : Intrinsics::dvs_default(W, H, false);
      SplatOptions o;
      o.atomics = SplatAtomics::fixed_point;  // the default path (automatic = fixed point)
      Trajectory identity;
      identity.transforms = {glm::dmat4(1.0)};
      RenderedClip r;
      try {
        r = render_clip(ctx(), f.rgb, f.depth, identity, K, o);
      } catch (const dvs::Error& e) {
        if (!forced || std::string(e.what()).rfind("render: ", 0) != 0) throw;
        --rendered;
        break;
      }
      const Worst w = against_input(r, f, H, W);
      // The input comes back within a hundredth of a level (the fixed-point weights and the neighbours' last-bit
      // projection offsets), every pixel visible.
      if (w.levels > 0.01 || w.hidden) {
        if (!failed++)
          first = std::to_string(H) + "x" + std::to_string(W) + (squash ? " (official intrinsics, metric)" : "") + ": " +
                  std::to_string(w.levels) + " levels at x=" + std::to_string(w.x) + " y=" + std::to_string(w.y) + ", " +
                  std::to_string(w.hidden) + " pixels hidden";
      }
    }
  }
  EXPECT_GT(rendered, 100) << "most sizes fit every limit the tests force";
  EXPECT_EQ(failed, 0) << failed << " of " << 2 * rendered << " renders differ from the input; the first: " << first;
}

}  // namespace
}  // namespace dvs::geometry
