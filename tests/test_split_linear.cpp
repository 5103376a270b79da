// Linear layers split over bounded sub-ranges (rows of X/Y/residual, weight rows with Y column slices, batch
// items) when forced limits make the operands exceed one binding / texel view / grid: the result must equal
// the unsplit call bitwise (same kernel, same K order per output), and the split must really happen (more
// dispatches). Odd sizes throughout.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "support/split_check.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_linear.hpp"
#include "tensor/tensor.hpp"

namespace dvs {
namespace {

using ops::Activation;
using ops::LinearEpilogue;
using ops::LinearShape;

Tensor random_tensor(vk::Context& c, int64_t n, DType dt, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  HostTensor h({n}, dt);
  for (int64_t i = 0; i < n; ++i) {
    float v = u(rng);
    if (dt == DType::f32) h.as<float>()[i] = v;
    else if (dt == DType::bf16) h.as<uint16_t>()[i] = f32_to_bf16(v);
    else h.as<uint16_t>()[i] = f32_to_f16(v);
  }
  return Tensor::upload(c, h);
}

struct Case {
  int64_t batch = 1, m = 37, n = 45, k = 24;
  DType w_dtype = DType::f32;
  bool epilogue = false;        // bias (bf16), GELU, modulation, gate, residual
  bool in_place = false;        // residual is Y
  bool per_item = false;        // batched weights and [batch, N] vectors
  int64_t x_lead = 0, y_pad = 0;  // unaligned X start; Y written as a column slice of wider rows
  std::string limits;           // forced inside the split run
};

struct Result {
  std::vector<float> y;
  uint32_t dispatches = 0;
  uint64_t noted = 0;  // "linear" splits this call noted
};

// Run for the device's family (texel on lavapipe) and for the tiled family (storage buffers: texel-view
// limits do not apply to it, binding and grid limits do).
class SplitLinearTest : public test::GpuTest, public testing::WithParamInterface<const char*> {
 protected:
  void SetUp() override {
    test::GpuTest::SetUp();
    tuning_.emplace(GetParam());
  }
  void TearDown() override {
    tuning_.reset();
    test::GpuTest::TearDown();
  }
  // The storage-buffer families (tiled, coopmat) run, whether the parameter or DVS_TUNING chose them.
  bool tiled() { return ops::device_tuning(ctx().caps()).linear != ops::KernelFamily::texel; }
  std::optional<ops::ScopedTuningOverride> tuning_;

  // Runs the case on fresh copies of the same data; `limits` empty: no extra limits.
  Result run(const Case& cs, const std::string& limits) {
    vk::Context& c = ctx();
    const int64_t B = cs.batch, M = cs.m, N = cs.n, K = cs.k, ldy = N + cs.y_pad;
    LinearShape s;
    s.batch = B;
    s.m = M;
    s.n = N;
    s.k = K;
    s.x_batch_stride = M * K;
    s.w_batch_stride = cs.per_item ? N * K : 0;
    s.y_batch_stride = M * ldy;
    s.vec_batch_stride = cs.per_item ? N : 0;
    s.y_row_stride = ldy;
    const int64_t vcount = cs.per_item ? B * N : N;
    Tensor xt = random_tensor(c, cs.x_lead + B * M * K, DType::f32, 1);
    Tensor x = cs.x_lead ? xt.rows(cs.x_lead, B * M * K) : xt;
    Tensor w = random_tensor(c, cs.per_item ? B * N * K : N * K, cs.w_dtype, 2);
    Tensor y = random_tensor(c, B * M * ldy, DType::f32, 3);  // the residual when in place; padding must survive
    LinearEpilogue ep;
    if (cs.epilogue) {
      ep.bias = random_tensor(c, N, DType::bf16, 4);
      ep.activation = Activation::gelu_tanh;
      ep.scale = random_tensor(c, vcount, DType::f32, 5);
      ep.shift = random_tensor(c, vcount, DType::f32, 6);
      ep.gate = random_tensor(c, vcount, DType::f32, 7);
      ep.residual = cs.in_place ? y : random_tensor(c, B * M * ldy, DType::f32, 8);
    }
    const ops::LinearKernel kern = ops::choose_linear_kernel(c, s, cs.w_dtype);  // chosen outside the limits
    Result r;
    {
      std::optional<test::ScopedLimits> scope;
      if (!limits.empty()) scope.emplace(c, limits);
      const uint64_t noted = test::split_count(c, "linear");
      ops::run_now(c, [&](vk::Recorder& rec) {
        ops::linear_batched_with(rec, x, w, y, s, ep, kern);
        r.dispatches = rec.dispatch_count();
      });
      r.noted = test::split_count(c, "linear") - noted;
    }
    r.y = y.download(c).to_f32();
    return r;
  }

  void check(const Case& cs) {
    SCOPED_TRACE(testing::Message() << "batch=" << cs.batch << " M=" << cs.m << " N=" << cs.n << " K=" << cs.k
                                    << " w=" << dtype_name(cs.w_dtype) << " limits " << cs.limits);
    Result plain = run(cs, ""), split = run(cs, cs.limits);
    // Without DVS_LIMITS the plain call is one dispatch; under a DVS_LIMITS profile it may split already.
    if (plain.dispatches == 1) {
      EXPECT_GT(split.dispatches, 1u) << "the forced limits did not split the call";
      EXPECT_EQ(plain.noted, 0u) << "the unsplit call noted a split";
    }
    else
      EXPECT_GE(split.dispatches, plain.dispatches);
    EXPECT_EQ(split.noted, 1u) << "a split call notes \"linear\" exactly once";
    ASSERT_EQ(plain.y.size(), split.y.size());
    EXPECT_EQ(std::memcmp(plain.y.data(), split.y.data(), plain.y.size() * 4), 0) << "split result differs";
  }
};

// X (37x13 f32: 481 scalar texels, K odd) over 256 texels: rows of X split; W and Y fit.
TEST_P(SplitLinearTest, RowsByTexels) {
  if (tiled()) GTEST_SKIP() << "storage buffers: no texel views";
  check({.m = 37, .n = 13, .k = 13, .limits = "texels=256"});
}

// The same X (1924 B) over a 1 KiB binding: rows of X split (the storage-buffer families' counterpart).
TEST_P(SplitLinearTest, RowsByBinding) {
  check({.m = 37, .n = 13, .k = 13, .limits = "binding=1KiB"});
}

// A bf16 weight of 45x24 (2160 B) over a 1 KiB binding with 3 rows of X: weight rows split, Y column slices.
TEST_P(SplitLinearTest, ColumnsByBinding) {
  check({.m = 3, .n = 45, .k = 24, .w_dtype = DType::bf16, .limits = "binding=1KiB"});
}

// Both: 37x45 with f32 weights and the full epilogue (bias, GELU, modulation, gate, residual).
TEST_P(SplitLinearTest, RowsAndColumnsWithEpilogue) {
  check({.m = 37, .n = 45, .k = 24, .epilogue = true, .limits = "binding=1KiB"});
  check({.m = 37, .n = 45, .k = 24, .epilogue = true, .in_place = true, .limits = "binding=1KiB,texels=256"});
}

// Batched weights and per-item vectors, Y a column slice of wider rows (padding untouched), X starting at
// an unaligned element (aligned-down binding + element offset), K not a multiple of 8 (scalar texels).
TEST_P(SplitLinearTest, BatchedStridedUnaligned) {
  check({.batch = 3, .m = 19, .n = 29, .k = 24, .epilogue = true, .per_item = true, .x_lead = 5, .y_pad = 7,
         .limits = "binding=1KiB"});
  check({.batch = 2, .m = 23, .n = 17, .k = 13, .w_dtype = DType::f16, .epilogue = true, .x_lead = 3, .y_pad = 2,
         .limits = "binding=1KiB,texels=256"});
}

// The grid: more row tiles than 64 workgroups (M = 2101 rows: over 64 tiles of 16 or 32 rows) splits the
// rows even though the bindings fit the device.
TEST_P(SplitLinearTest, RowsByGrid) {
  // The tiled family: more than 64 tiles of the tuning's tile_m rows.
  const int64_t m = tiled() ? 65 * int64_t(ops::device_tuning(ctx().caps()).linear_tile_m) + 37 : 2101;
  check({.m = m, .n = 5, .k = 8, .limits = "groups=64"});
}

// One row of X (K = 520: 2080 B) over a 1 KiB binding: split over K, each later chunk adding its partial
// products to Y (bias on the first, residual in place). Another summation order: equal within fp32
// rounding, not bitwise.
TEST_P(SplitLinearTest, KChunksAccumulate) {
  for (int64_t K : {520, 523}) {  // vec8 steps, scalar texels
    SCOPED_TRACE("K=" + std::to_string(K));
    vk::Context& c = ctx();
    Tensor x = random_tensor(c, 5 * K, DType::f32, 1), w = random_tensor(c, 3 * K, DType::bf16, 2);
    Tensor bias = random_tensor(c, 3, DType::f32, 3);
    LinearShape s;
    s.m = 5;
    s.n = 3;
    s.k = K;
    std::vector<float> plain, split;
    uint32_t dispatches = 0;
    for (bool limited : {false, true}) {
      Tensor y = random_tensor(c, 15, DType::f32, 4);
      LinearEpilogue ep;
      ep.bias = bias;
      ep.residual = y;
      std::optional<test::ScopedLimits> scope;
      if (limited) scope.emplace(c, "binding=1KiB,texels=256");
      ops::run_now(c, [&](vk::Recorder& rec) {
        ops::linear_batched(rec, x, w, y, s, ep);
        dispatches = rec.dispatch_count();
      });
      scope.reset();
      (limited ? split : plain) = y.download(c).to_f32();
    }
    EXPECT_GT(dispatches, 1u);
    for (size_t i = 0; i < plain.size(); ++i) EXPECT_NEAR(split[i], plain[i], 1e-4 * (1 + std::abs(plain[i]))) << i;
  }
}

// With an activation the K chunks cannot be summed after the epilogue: a clear error, not a bad dispatch.
TEST_P(SplitLinearTest, KSplitWithActivationIsAnError) {
  vk::Context& c = ctx();
  Tensor x = random_tensor(c, 2 * 520, DType::f32, 1), w = random_tensor(c, 3 * 520, DType::f32, 2);
  Tensor y = Tensor::empty(c, {2, 3}, DType::f32);
  test::ScopedLimits l(c, "binding=1KiB,texels=256");
  LinearShape s;
  s.m = 2;
  s.n = 3;
  s.k = 520;
  LinearEpilogue ep;
  ep.activation = Activation::silu;
  try {
    ops::run_now(c, [&](vk::Recorder& rec) { ops::linear_batched(rec, x, w, y, s, ep); });
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("K split"), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(Family, SplitLinearTest, testing::Values("", "linear=tiled"),
                         [](const testing::TestParamInfo<const char*>& i) {
                           return std::string(i.param).empty() ? std::string("device") : std::string("tiled");
                         });

}  // namespace
}  // namespace dvs
