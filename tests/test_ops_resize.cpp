// resize_bilinear against a plain double-precision reference of PyTorch's rule (F.interpolate bilinear, sizes
// given, both align_corners settings), on odd sizes up and down; and its split paths (plane chunks and row
// chunks within a plane) bitwise equal to the unsplit call.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "support/gpu.hpp"
#include "support/split_check.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_resize.hpp"

namespace dvs {
namespace {

std::vector<float> random_planes(int64_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(-3.0f, 3.0f);
  std::vector<float> v(static_cast<size_t>(n));
  for (float& x : v) x = d(rng);
  return v;
}

std::vector<double> reference(const std::vector<float>& x, int64_t planes, int64_t h, int64_t w, int64_t ho, int64_t wo,
                              bool align_corners) {
  auto src = [&](int64_t d, int64_t in, int64_t out, int64_t& i0, int64_t& i1, double& l) {
    // PyTorch keeps the scale and the source coordinate in fp32 (opmath of float); the blend is in double here.
    const float scale = align_corners ? (out > 1 ? float(in - 1) / float(out - 1) : 0.0f) : float(in) / float(out);
    const double s = align_corners ? double(scale * float(d)) : double(std::max(scale * (float(d) + 0.5f) - 0.5f, 0.0f));
    i0 = std::min<int64_t>(int64_t(std::floor(s)), in - 1);
    i1 = std::min<int64_t>(i0 + 1, in - 1);
    l = std::clamp(s - double(i0), 0.0, 1.0);
  };
  std::vector<double> y(size_t(planes * ho * wo));
  for (int64_t p = 0; p < planes; ++p)
    for (int64_t oy = 0; oy < ho; ++oy)
      for (int64_t ox = 0; ox < wo; ++ox) {
        int64_t y0, y1, x0, x1;
        double ly, lx;
        src(oy, h, ho, y0, y1, ly);
        src(ox, w, wo, x0, x1, lx);
        auto at = [&](int64_t r, int64_t c) { return double(x[size_t((p * h + r) * w + c)]); };
        y[size_t((p * ho + oy) * wo + ox)] =
            (1 - ly) * ((1 - lx) * at(y0, x0) + lx * at(y0, x1)) + ly * ((1 - lx) * at(y1, x0) + lx * at(y1, x1));
      }
  return y;
}

class ResizeBilinear : public test::GpuTest {};

TEST_F(ResizeBilinear, MatchesReferenceUpAndDownOnOddSizes) {
  struct Case {
    Shape x, y;
  };
  // DPT fusion (x2 of an odd grid), the depth output's upsampling (model size -> frame size), downscaling,
  // one-pixel axes (align_corners scale 0) and a rank-3 tensor.
  const std::vector<Case> cases = {{{2, 3, 3, 4}, {2, 3, 6, 8}},     {{3, 5, 7, 9}, {3, 5, 13, 17}},
                                   {{1, 2, 42, 56}, {1, 2, 48, 64}}, {{2, 1, 11, 13}, {2, 1, 5, 4}},
                                   {{1, 3, 1, 5}, {1, 3, 4, 1}},     {{5, 9, 7}, {5, 10, 3}}};
  uint32_t seed = 3;
  for (const Case& c : cases)
    for (bool ac : {true, false}) {
      const int64_t planes = shape_numel(c.x) / (c.x[c.x.size() - 2] * c.x.back());
      const auto xs = random_planes(shape_numel(c.x), seed++);
      Tensor x = Tensor::upload(ctx(), HostTensor::from_f32(c.x, xs)), y = Tensor::empty(ctx(), c.y, DType::f32);
      ops::run_now(ctx(), [&](vk::Recorder& r) { ops::resize_bilinear(r, x, y, ac); });
      const auto got = y.download(ctx()).to_f32();
      const auto want = reference(xs, planes, c.x[c.x.size() - 2], c.x.back(), c.y[c.y.size() - 2], c.y.back(), ac);
      double worst = 0;
      for (size_t i = 0; i < want.size(); ++i) worst = std::max(worst, std::abs(double(got[i]) - want[i]));
      EXPECT_LT(worst, 2e-6) << shape_str(c.x) << " -> " << shape_str(c.y) << " align_corners " << ac;
    }
}

TEST_F(ResizeBilinear, SplitsOverPlanesAndRowsBitwise) {
  struct Case {
    Shape x, y;
    const char* limits;
  };
  // binding=4KiB: 1024 floats. [7, 19, 23] planes (437 floats) -> [7, 31, 29] (899): plane chunks.
  // [2, 61, 37] (2257 floats a plane) -> [2, 45, 70] (3150): neither plane fits, rows within a plane.
  const std::vector<Case> cases = {{{7, 19, 23}, {7, 31, 29}, "binding=4KiB,groups=64"},
                                   {{2, 61, 37}, {2, 45, 70}, "binding=4KiB,groups=64"}};
  uint32_t seed = 11;
  for (const Case& c : cases)
    for (bool ac : {true, false}) {
      Tensor x = Tensor::upload(ctx(), HostTensor::from_f32(c.x, random_planes(shape_numel(c.x), seed++)));
      test::expect_split_equal(ctx(), c.limits, c.y, DType::f32,
                               [&](vk::Recorder& r, const Tensor& y) { ops::resize_bilinear(r, x, y, ac); },
                               "resize " + shape_str(c.x) + " -> " + shape_str(c.y));
    }
}

}  // namespace
}  // namespace dvs
