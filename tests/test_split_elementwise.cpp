// Elementwise ops, casts and random fills split over flat element ranges: under limits forced small enough
// that a tensor spans many bindings, every op gives bitwise the result of the call under the limits in force
// before (unsplit, or split less under DVS_LIMITS), and really splits (more dispatches).
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <random>
#include <vector>

#include "dvs/error.hpp"
#include "support/gpu.hpp"
#include "support/texel_paths.hpp"
#include "support/scoped_limits.hpp"
#include "support/split_check.hpp"
#include "tensor/ops_check.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_random.hpp"

namespace dvs {
namespace {

// binding=1KiB: 256 f32 per binding, so every tensor below (thousands of elements) splits; the texel limit
// is left alone here (texel views are chosen per chunk and covered by TexelLimitFallsBackPerChunk).
constexpr const char* kSplitLimits = "binding=1KiB,groups=64";

class SplitElementwise : public test::TexelPathsTest {
 protected:

  uint32_t run(const std::function<void(vk::Recorder&)>& record) { return test::run_counted(ctx(), record); }

  void expect_split_equal(const Shape& out_shape, DType dtype,
                          const std::function<void(vk::Recorder&, const Tensor&)>& op, const std::string& what) {
    test::expect_split_equal(ctx(), kSplitLimits, out_shape, dtype, op, what);
  }
};
DVS_TEXEL_PATHS(SplitElementwise, SplitElementwise);

Tensor random_tensor(vk::Context& ctx, const Shape& s, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(-4.0f, 4.0f);
  std::vector<float> v(size_t(shape_numel(s)));
  for (float& x : v) x = d(rng);
  return Tensor::upload(ctx, HostTensor::from_f32(s, v));
}

// Odd element counts (scalar shaders, a vec4 body with a scalar tail) and multiples of 4 (vec4 shaders).
// Rows and channels stay within one 1KiB binding (a larger broadcast operand is refused, see below).
const std::vector<Shape> kShapes = {{29, 5, 67}, {16, 251}, {7, 3, 211}, {6, 5, 136}, {2, 12, 172}, {2, 9, 174}};

TEST_P(SplitElementwise, UnaryOpsSplitOverElementRanges) {
  for (const Shape& s : kShapes) {
    const Tensor x = random_tensor(ctx(), s, 1);
    const std::string at = " [" + shape_str(s) + "]";
    expect_split_equal(s, DType::f32, [&](vk::Recorder& r, const Tensor& y) { ops::scale(r, x, y, 1.5f, -0.25f); },
                       "scale" + at);
    expect_split_equal(s, DType::f32, [&](vk::Recorder& r, const Tensor& y) { ops::silu(r, x, y); }, "silu" + at);
    expect_split_equal(s, DType::f32, [&](vk::Recorder& r, const Tensor& y) { ops::gelu_tanh(r, x, y); }, "gelu" + at);
    expect_split_equal(s, DType::f32, [&](vk::Recorder& r, const Tensor& y) { ops::clamp(r, x, y, -1, 2); },
                       "clamp" + at);
  }
}

// Second-operand shapes for x of shape s: same shape, scalar, row vector [D] and per-channel [C, 1] (C the
// middle dimension), so chunks start mid-row and mid-channel.
std::vector<Shape> broadcast_shapes(const Shape& s) {
  std::vector<Shape> out = {s, {1}, {s.back()}};
  if (s.size() == 3) out.push_back({s[1], 1});
  return out;
}

TEST_P(SplitElementwise, BinaryOpsKeepBroadcastAcrossChunks) {
  for (const Shape& s : kShapes) {
    const Tensor x = random_tensor(ctx(), s, 2);
    for (const Shape& ys : broadcast_shapes(s)) {
      const Tensor y = random_tensor(ctx(), ys, 3);
      const std::string at = " [" + shape_str(s) + "] by [" + shape_str(ys) + "]";
      expect_split_equal(s, DType::f32, [&](vk::Recorder& r, const Tensor& z) { ops::add(r, x, y, z); }, "add" + at);
      expect_split_equal(s, DType::f32, [&](vk::Recorder& r, const Tensor& z) { ops::mul(r, x, y, z); }, "mul" + at);
      expect_split_equal(s, DType::f32, [&](vk::Recorder& r, const Tensor& z) { ops::axpby(r, 0.5f, x, -2.0f, y, z); },
                         "axpby" + at);
    }
  }
}

TEST_P(SplitElementwise, ScaleShiftKeepsBroadcastAcrossChunks) {
  for (const Shape& s : kShapes) {
    const Tensor x = random_tensor(ctx(), s, 4);
    for (const Shape& ss : broadcast_shapes(s)) {
      const Tensor sc = random_tensor(ctx(), ss, 5), sh = random_tensor(ctx(), ss, 6);
      expect_split_equal(s, DType::f32, [&](vk::Recorder& r, const Tensor& z) { ops::scale_shift(r, x, sc, sh, z, 1.0f); },
                         "scale_shift [" + shape_str(s) + "] by [" + shape_str(ss) + "]");
    }
  }
}

// An operand larger than one 1KiB binding (as the transformer's positional table added over the batch): each
// chunk binds the window of it that chunk reads. Periods that are / are not multiples of 4, row and channel
// broadcasts, a window start that is not a multiple of anything.
TEST_P(SplitElementwise, BroadcastOperandLargerThanABindingIsReadThroughWindows) {
  const std::vector<std::pair<Shape, Shape>> cases = {
      {{3, 300}, {300}}, {{5, 3, 300}, {3, 300}}, {{2, 1500, 3}, {1500, 1}}, {{2, 1001, 4}, {1001, 1}},
      {{3, 1001, 4}, {1001, 4}}};
  for (const auto& [xs, ys] : cases) {
    const Tensor x = random_tensor(ctx(), xs, 7), y = random_tensor(ctx(), ys, 8), t = random_tensor(ctx(), ys, 9);
    const std::string at = " [" + shape_str(xs) + "] by [" + shape_str(ys) + "]";
    ctx().reset_splits();
    expect_split_equal(xs, DType::f32, [&](vk::Recorder& r, const Tensor& z) { ops::add(r, x, y, z); }, "add" + at);
    expect_split_equal(xs, DType::f32, [&](vk::Recorder& r, const Tensor& z) { ops::scale_shift(r, x, y, t, z, 1.0f); },
                       "scale_shift" + at);
    EXPECT_GT(ctx().splits().count("add"), 0u) << at;
  }
  // A period that is no binding offset cannot start a chunk: refused, naming the op and the period.
  const Tensor x = random_tensor(ctx(), {3, 301}, 7), y = random_tensor(ctx(), {301}, 8);
  const Tensor z = Tensor::zeros(ctx(), {3, 301}, DType::f32);
  test::ScopedLimits limits(ctx(), kSplitLimits);
  try {
    run([&](vk::Recorder& r) { ops::add(r, x, y, z); });
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("period of 301 elements"), std::string::npos) << e.what();
  }
}

TEST_P(SplitElementwise, CastsSplitInWholeWords) {
  const int64_t n = 5001;  // odd: the last 16-bit word is half the tensor's, half its slack
  const Tensor x = random_tensor(ctx(), {n}, 9);
  for (DType to : {DType::bf16, DType::f16, DType::i32}) {
    expect_split_equal({n}, to, [&](vk::Recorder& r, const Tensor& y) { ops::cast(r, x, y); },
                       std::string("cast to ") + dtype_name(to));
    const Tensor narrow = Tensor::zeros(ctx(), {n}, to);
    run([&](vk::Recorder& r) { ops::cast(r, x, narrow); });
    expect_split_equal({n}, DType::f32, [&](vk::Recorder& r, const Tensor& y) { ops::cast(r, narrow, y); },
                       std::string("cast from ") + dtype_name(to));
  }
}

TEST_P(SplitElementwise, RandomFillsSplitWithCounterOffset) {
  const Shape s = {3, 1667};
  const ops::RandomStream st{1234, 5, 3};  // base 3: the first Philox block is skewed
  expect_split_equal(s, DType::f32, [&](vk::Recorder& r, const Tensor& y) { ops::random_uniform(r, y, st, -1, 2); }, "uniform");
  expect_split_equal(s, DType::f32, [&](vk::Recorder& r, const Tensor& y) { ops::random_normal(r, y, st, 0.5f, 2); }, "normal");
  expect_split_equal(s, DType::i32, [&](vk::Recorder& r, const Tensor& y) { ops::random_below(r, y, st, 1000); }, "below");
}

// A texel limit below the tensor's vec4 count but a binding that holds it: no split, the storage shaders take
// over (no texel view over maxTexelBufferElements), same result.
TEST_P(SplitElementwise, TexelLimitFallsBackPerChunk) {
  const Shape s = {4, 1001};
  const Tensor x = random_tensor(ctx(), s, 10), y = random_tensor(ctx(), {1001}, 11);
  const Tensor a = Tensor::zeros(ctx(), s, DType::f32), b = Tensor::zeros(ctx(), s, DType::f32);
  run([&](vk::Recorder& r) { ops::mul(r, x, y, a); });
  {
    test::ScopedLimits limits(ctx(), "texels=256");
    run([&](vk::Recorder& r) { ops::mul(r, x, y, b); });
  }
  EXPECT_EQ(a.download(ctx()).to_f32(), b.download(ctx()).to_f32());
}

TEST_P(SplitElementwise, NonFiniteScanSplitsOverRanges) {
  std::vector<float> v(5003, 1.0f);
  v[1777] = std::numeric_limits<float>::quiet_NaN();
  v[4001] = std::numeric_limits<float>::infinity();
  v[5002] = -std::numeric_limits<float>::infinity();
  const Tensor t = Tensor::upload(ctx(), HostTensor::from_f32({int64_t(v.size())}, v));
  auto scan = [&](std::vector<ops::NonFiniteHit>& hits) {
    ops::NonFiniteCheck check(ctx(), 1);
    const uint32_t d = run([&](vk::Recorder& r) { check.record(r, t, "t"); });
    hits = check.hits();
    return d;
  };
  std::vector<ops::NonFiniteHit> whole, split;
  const uint32_t d_whole = scan(whole);
  uint32_t d_split = 0;
  {
    test::ScopedLimits limits(ctx(), kSplitLimits);
    d_split = scan(split);
  }
  EXPECT_GT(d_split, d_whole);
  ASSERT_EQ(whole.size(), 1u);
  ASSERT_EQ(split.size(), 1u);
  EXPECT_EQ(split[0].count, 3u);
  EXPECT_EQ(split[0].first, 1777);
  EXPECT_EQ(whole[0].count, split[0].count);
  EXPECT_EQ(whole[0].first, split[0].first);
}

}  // namespace
}  // namespace dvs
