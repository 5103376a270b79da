// Convolutions and resampling under forced limits (test::ScopedLimits, as DVS_LIMITS would force them): each
// limit takes its own split path, the result equals the unsplit call, and the split really happened (more
// dispatches than the unsplit call). Sizes are odd on purpose (C_in 5, C_out 7, F 5, H 13, W 11).
//
// Which limit forces which split (engine/src/tensor/ops_conv.cpp, record_conv):
//  - binding: y bound per group of output channels, then chunks of output frames / rows / columns, the
//    weights and x read through aligned sub-views;
//  - texels:  the repacked input chunk (an RGBA32F texel view) shrinks to rows / columns, and the pack reads x
//    (an R32F view) in groups of channels and frames;
//  - groups:  GEMM chunks of at most groups x tile pixels; resampling grids over planes / rows;
//  - alloc:   the repacked weights (recorder scratch, one allocation) in groups of output channels;
//  - one output pixel of all input channels over one binding: input channels in chunks with accumulation.
// Equality: bitwise wherever the per-output sum keeps its order (every split but input-channel chunks);
// input-channel chunks add partial sums, |split - whole| <= 1e-5 * (|whole| + 1).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv.hpp"

namespace dvs {
namespace {

using test::GpuTest;

Tensor random_tensor(vk::Context& c, const Shape& s, uint32_t seed, float scale, DType dt = DType::f32) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(-scale, scale);
  std::vector<float> v(size_t(shape_numel(s)));
  for (float& x : v) x = d(rng);
  HostTensor h = HostTensor::from_f32(s, v);
  if (dt == DType::bf16) {
    HostTensor b(s, DType::bf16);
    for (size_t i = 0; i < v.size(); ++i) b.as<uint16_t>()[i] = f32_to_bf16(v[i]);
    h = b;
  }
  return Tensor::upload(c, h);
}

std::vector<float> values(vk::Context& c, const Tensor& t) {
  HostTensor h = t.download(c);
  std::vector<float> v(size_t(t.numel()));
  std::memcpy(v.data(), h.data.data(), v.size() * 4);
  return v;
}

// Runs `op` (recording into a fresh y) and returns y's values and the recording's dispatch count.
struct Result {
  std::vector<float> y;
  uint32_t dispatches = 0;
};
// `limits`: forced for the recording only (y is allocated before, it may exceed the forced alloc limit).
Result run(vk::Context& c, const Shape& y_shape, const std::function<void(vk::Recorder&, const Tensor&)>& op,
           const char* limits = nullptr) {
  Tensor y = Tensor::empty(c, y_shape, DType::f32);
  Result r;
  {
    std::unique_ptr<test::ScopedLimits> scope;
    if (limits) scope = std::make_unique<test::ScopedLimits>(c, limits);
    ops::run_now(c, [&](vk::Recorder& rec) {
      op(rec, y);
      r.dispatches = rec.dispatch_count();
    });
  }
  r.y = values(c, y);
  return r;
}

// The split must have happened: more dispatches than the unsplit call (unless DVS_LIMITS already splits the
// unsplit call, as the tiny-limits CI profile does; then equality is what this checks).
void expect_split(const Result& whole, const Result& split, const std::string& what) {
  if (!std::getenv("DVS_LIMITS")) EXPECT_GT(split.dispatches, whole.dispatches) << what << ": did not split";
}

void expect_bitwise(const Result& whole, const Result& split, const std::string& what) {
  ASSERT_EQ(whole.y.size(), split.y.size());
  size_t bad = 0;
  for (size_t i = 0; i < whole.y.size(); ++i)
    if (std::memcmp(&whole.y[i], &split.y[i], 4) != 0 && bad++ < 5)
      ADD_FAILURE() << what << ": element " << i << " " << split.y[i] << " != " << whole.y[i];
  EXPECT_EQ(bad, 0u) << what;
  expect_split(whole, split, what);
}

class SplitConv : public GpuTest {
 protected:
  static constexpr int64_t kCin = 5, kCout = 7, kF = 5, kH = 13, kW = 11;
  // Every conv path of the VAE on one input: causal 3x3x3 (first batch and with a cache, plus the cache
  // update), conv2d 3x3, stride-2 downsample, 1x1, upsample x2 + 3x3 fused (time compressed).
  std::vector<Result> all_convs(const char* limits) {
    vk::Context& c = ctx();
    if (!x_.buffer().valid()) {
      x_ = random_tensor(c, {1, kCin, kF, kH, kW}, 1, 1.f);
      cache_ = random_tensor(c, {1, kCin, 2, kH, kW}, 2, 1.f);
      w3_ = random_tensor(c, {kCout, kCin, 3, 3, 3}, 3, 0.2f, DType::bf16);
      w2_ = random_tensor(c, {kCout, kCin, 3, 3}, 4, 0.2f, DType::bf16);
      w1_ = random_tensor(c, {kCout, kCin, 1, 1, 1}, 5, 0.4f, DType::f32);
      b_ = random_tensor(c, {kCout}, 6, 0.5f, DType::bf16);
      b1_ = random_tensor(c, {kCout}, 7, 0.5f, DType::f32);
    }
    std::unique_ptr<test::ScopedLimits> scope;
    if (limits) scope = std::make_unique<test::ScopedLimits>(c, limits);
    const Shape y = {1, kCout, kF, kH, kW};
    Shape down = ops::conv2d_shape(x_.shape(), w2_.shape(), ops::Conv2dParams::downsample3x3());
    Shape upc = ops::upsample2x_shape(x_.shape(), true);
    upc[1] = kCout;
    Tensor cache_out = Tensor::empty(c, {1, kCin, 2, kH, kW}, DType::f32);
    std::vector<Result> r;
    r.push_back(run(c, y, [&](vk::Recorder& rec, const Tensor& o) { ops::causal_conv3d(rec, x_, w3_, &b_, o, nullptr, &cache_out); }));
    r.push_back({values(c, cache_out), 0});
    r.push_back(run(c, y, [&](vk::Recorder& rec, const Tensor& o) { ops::causal_conv3d(rec, x_, w3_, &b_, o, &cache_, &cache_out); }));
    r.push_back({values(c, cache_out), 0});
    r.push_back(run(c, y, [&](vk::Recorder& rec, const Tensor& o) { ops::conv2d(rec, x_, w2_, &b_, o, ops::Conv2dParams::same3x3()); }));
    r.push_back(run(c, down, [&](vk::Recorder& rec, const Tensor& o) { ops::conv2d(rec, x_, w2_, nullptr, o, ops::Conv2dParams::downsample3x3()); }));
    r.push_back(run(c, y, [&](vk::Recorder& rec, const Tensor& o) { ops::conv1x1(rec, x_, w1_, &b1_, o); }));
    r.push_back(run(c, upc, [&](vk::Recorder& rec, const Tensor& o) { ops::upsample2x_conv3x3(rec, x_, w2_, &b_, o, true); }));
    return r;
  }
  void compare_all(const char* limits, const std::vector<size_t>& must_split) {
    std::vector<Result> whole = all_convs(nullptr), split = all_convs(limits);
    const char* names[] = {"causal conv", "its cache", "causal conv with cache", "its cache (in place)", "conv2d 3x3",
                           "downsample 3x3 s2", "conv 1x1", "upsample x2 + conv 3x3"};
    for (size_t i = 0; i < whole.size(); ++i) {
      const std::string what = std::string(names[i]) + " under " + limits;
      ASSERT_EQ(whole[i].y.size(), split[i].y.size());
      for (size_t k = 0; k < whole[i].y.size(); ++k)
        ASSERT_EQ(std::memcmp(&whole[i].y[k], &split[i].y[k], 4), 0) << what << ": element " << k;
    }
    for (size_t i : must_split) expect_split(whole[i], split[i], std::string(names[i]) + " under " + limits);
  }
  Tensor x_, cache_, w3_, w2_, w1_, b_, b1_;
};

// binding=1KiB (the least DVS_LIMITS takes): 256 floats per binding; y's 143-float planes are bound per output channel group and a row
// chunk, the packed input (8 padded channels = 32 B a pixel) holds a few rows.
TEST_F(SplitConv, BindingSplitsChannelGroupsRowsAndColumns) { compare_all("binding=1KiB", {0, 2, 4, 5, 6, 7}); }

// texels=256 (the least DVS_LIMITS takes): an R32F view of x holds 256 floats (less than one channel's
// 5 x 143): the pack reads x per channel and group of frames; RGBA32F views of the packed input hold 256 pixels.
TEST_F(SplitConv, TexelsSplitPackAndRows) { compare_all("texels=256", {0, 2, 4, 6, 7}); }

// groups=64: at most 64 x tile pixels per GEMM dispatch (the fused upsample makes 9 x 26 x 22 = 5148).
// With the GPU's tiled family (DVS_TUNING=gpu) a 128-pixel tile needs only 41 groups here: the smallest tile
// (32 pixels, 161 groups) keeps the split in the test (the texel family ignores the field).
TEST_F(SplitConv, GroupsSplitTheGrid) {
  ops::ScopedTuningOverride tile("conv_tile_m=32");
  compare_all("groups=64", {7});
}

// alloc=64KiB (the least DVS_LIMITS takes): the repacked weights of 41 x 37 x 3x3x3 bf16 (41 x 27 x 40 x 2 B
// = 86 KiB, recorder scratch: one allocation) are packed per group of 30 output channels.
TEST_F(SplitConv, AllocSplitsPackedWeights) {
  vk::Context& c = ctx();
  const int64_t cin = 37, cout = 41;
  Tensor x = random_tensor(c, {1, cin, 2, 5, 7}, 31, 1.f), w = random_tensor(c, {cout, cin, 3, 3, 3}, 32, 0.1f, DType::bf16);
  Tensor b = random_tensor(c, {cout}, 33, 0.5f, DType::bf16);
  auto op = [&](vk::Recorder& rec, const Tensor& o) { ops::causal_conv3d(rec, x, w, &b, o); };
  Result whole = run(c, {1, cout, 2, 5, 7}, op), split;
  {
    test::ScopedLimits l(c, "alloc=64KiB");
    split = run(c, {1, cout, 2, 5, 7}, op);
  }
  expect_bitwise(whole, split, "packed weights under alloc=64KiB");
}

// The tiny-limits profile of CI, all at once.
TEST_F(SplitConv, TinyProfile) { compare_all("binding=4KiB,texels=1024,alloc=256KiB,groups=64", {}); }

// 37 input channels (padded to 40): one output pixel of a 3x3x3 conv repacks 27 x 40 floats = 4.2 KiB, over a
// 4 KiB binding, so input channels run in chunks (32 + 5) that add into y.
TEST_F(SplitConv, InputChannelChunksAccumulate) {
  vk::Context& c = ctx();
  const int64_t cin = 37;
  Tensor x = random_tensor(c, {1, cin, 3, 5, 7}, 11, 1.f), w = random_tensor(c, {kCout, cin, 3, 3, 3}, 12, 0.1f, DType::bf16);
  Tensor b = random_tensor(c, {kCout}, 13, 0.5f, DType::bf16);
  auto op = [&](vk::Recorder& rec, const Tensor& o) { ops::causal_conv3d(rec, x, w, &b, o); };
  Result whole = run(c, {1, kCout, 3, 5, 7}, op);
  Result split;
  {
    test::ScopedLimits l(c, "binding=4KiB");
    split = run(c, {1, kCout, 3, 5, 7}, op);
  }
  ASSERT_EQ(whole.y.size(), split.y.size());
  for (size_t i = 0; i < whole.y.size(); ++i)
    ASSERT_LE(std::fabs(split.y[i] - whole.y[i]), 1e-5f * (std::fabs(whole.y[i]) + 1.f)) << "element " << i;
  expect_split(whole, split, "input-channel chunks");
}

// The resampling ops: planes (z) and rows per dispatch within binding and grid limits; bitwise equal.
// Many small planes (67 channels: over 64 workgroups in z) and a few large ones (a 26 x 22 upsampled plane
// is 572 floats, over a 1 KiB binding: row chunks).
TEST_F(SplitConv, ResamplingSplitsPlanesAndRows) {
  vk::Context& c = ctx();
  Tensor many = random_tensor(c, {1, 67, 3, 5, 7}, 21, 1.f), large = random_tensor(c, {1, 2, 3, kH, kW}, 22, 1.f);
  struct Case {
    const char* name;
    Shape y;
    std::function<void(vk::Recorder&, const Tensor&)> op;
  };
  const std::vector<Case> cases = {
      {"upsample2x, many planes", ops::upsample2x_shape(many.shape(), true),
       [&](vk::Recorder& rec, const Tensor& o) { ops::upsample2x(rec, many, o, true); }},
      {"upsample2x, large planes", ops::upsample2x_shape(large.shape(), false),
       [&](vk::Recorder& rec, const Tensor& o) { ops::upsample2x(rec, large, o, false); }},
      {"avgpool_time_pairs, many planes", {1, 67, ops::downsample_time_frames(3), 5, 7},
       [&](vk::Recorder& rec, const Tensor& o) { ops::avgpool_time_pairs(rec, many, o); }},
      {"upsample_nearest, many planes", {1, 67, 2, 9, 11},
       [&](vk::Recorder& rec, const Tensor& o) { ops::upsample_nearest(rec, many, o, true); }},
      {"upsample_nearest, large planes", {1, 2, 3, 27, 17},
       [&](vk::Recorder& rec, const Tensor& o) { ops::upsample_nearest(rec, large, o, false); }},
  };
  for (const char* limits : {"binding=1KiB", "groups=64", "binding=4KiB,texels=1024,alloc=256KiB,groups=64"}) {
    for (const Case& k : cases) {
      if (std::string(limits) == "groups=64" && k.y[1] < 64) continue;  // nothing over 64 workgroups to split
      Result whole = run(c, k.y, k.op), split = run(c, k.y, k.op, limits);
      expect_bitwise(whole, split, std::string(k.name) + " under " + limits);
    }
  }
}

}  // namespace
}  // namespace dvs
