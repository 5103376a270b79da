// Linear / GEMM against a plain C++ reference (double accumulation) on random data, for every kernel family
// (the fixture and its tolerance: support/linear_test.hpp). The tensor-core kernel's own paths:
// test_ops_linear_coopmat.cpp; the instantiations below cover the TEST_Ps of both files.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/linear_test.hpp"

namespace dvs {
namespace {

// LinearTest, Options, make_host, random_values and the ops names they use (support/linear_test.hpp).
using namespace test;

TEST_P(LinearTest, OddShapesF32) {
  const int64_t shapes[][3] = {{1, 1, 1},   {7, 33, 129}, {33, 7, 64},  {129, 33, 40}, {1, 100, 256},
                               {2, 17, 72}, {3, 9, 16},   {4, 65, 24},  {5, 40, 7},    {17, 49, 8},
                               {40, 100, 96}};
  for (auto& s : shapes) check(s[0], s[1], s[2], {});
}

TEST_P(LinearTest, SixteenBitWeights) {
  // (Each weight type x tile is a pipeline LLVM compiles on first use: the f16 cases stay few.)
  for (DType dt : {DType::bf16, DType::f16}) {
    Options o;
    o.w_dtype = dt;
    check(33, 47, 64, o);   // vectorised K steps
    check(9, 17, 37, o);    // scalar path (K not a multiple of 8)
    if (dt == DType::bf16) {
      check(1, 70, 128, o);  // GEMV-like
      check(3, 5, 24, o);
    }
  }
}

TEST_P(LinearTest, LargeKSmallN) {
  check(3, 2, 5000, {});
  Options o;
  o.w_dtype = DType::bf16;
  check(1, 5, 4104, o);
}

TEST_P(LinearTest, ZeroK) {
  Options o;
  o.bias = true;
  check(5, 9, 0, o);
}

TEST_P(LinearTest, Epilogues) {
  Options o;
  o.bias = true;
  check(19, 35, 48, o);
  o.bias_dtype = DType::bf16;
  o.w_dtype = DType::bf16;
  o.act = Activation::gelu_tanh;
  check(19, 35, 48, o);
  o.bias_dtype = DType::f16;
  o.act = Activation::silu;
  check(10, 37, 16, o);
  o.act = Activation::gelu_erf;  // DINOv2's MLP: the exact GELU, with LayerScale as the gate (below)
  check(13, 41, 24, o);
  Options g;
  g.w_dtype = DType::bf16;
  g.bias = true;
  g.bias_dtype = DType::bf16;
  g.act = Activation::gelu_tanh;
  g.gate = true;
  g.residual = true;
  check(21, 29, 56, g);  // gated residual: y = r + gate ⊙ gelu(xWᵀ + b)
  g.gate = false;
  check(21, 29, 56, g);  // plain residual
  g.residual = false;
  g.gate = true;
  check(6, 11, 8, g);    // gate alone
  g.act = Activation::gelu_erf;
  g.gate = g.residual = true;
  check(9, 27, 40, g);
  Options m;
  m.modulation = true;
  m.bias = true;
  check(12, 23, 40, m);  // y = (xWᵀ + b) ⊙ (1 + scale) + shift
  m.act = Activation::silu;
  m.gate = true;
  m.residual = true;
  check(12, 23, 40, m);
}

TEST_P(LinearTest, ResidualInPlace) {
  Options o;
  o.residual = true;
  o.in_place = true;
  o.gate = true;
  o.bias = true;
  check(13, 27, 32, o);
  o.w_dtype = DType::bf16;
  check(1, 27, 32, o);
}

TEST_P(LinearTest, BatchedStrided) {
  Options o;
  o.batch = 3;
  check(9, 20, 24, o);  // shared weight
  o.shared_weight = false;
  o.w_dtype = DType::bf16;
  check(9, 20, 24, o);
  o.per_item_vectors = true;
  o.gate = true;
  o.residual = true;
  o.modulation = true;
  check(17, 12, 32, o);  // per-item gate/scale/shift (CogVideoX: one per batch item)
  Options p;
  p.batch = 2;
  p.x_pad = 8;
  p.y_pad = 3;
  check(10, 13, 16, p);  // row strides larger than the rows
  p.x_pad = 1;           // odd X row stride: scalar path
  check(10, 13, 16, p);
  p.kernel = LinearKernel{};  // even when a vectorised kernel is asked for
  check(10, 13, 16, p);
}

TEST_P(LinearTest, UnalignedSlices) {
  Options o;
  o.x_lead = 3;
  o.w_lead = 5;
  o.y_lead = 1;
  check(11, 19, 16, o);  // offsets force the scalar path
  o.x_lead = 4;
  o.w_lead = 8;
  o.w_dtype = DType::bf16;
  o.residual = true;
  check(11, 19, 16, o);  // offsets on texel boundaries but not on allocation boundaries: vectorised
}

TEST_P(LinearTest, KernelVariants) {
  // Variants the selector picks on other devices (cluster shuffles for wider subgroups, no subgroup
  // operations) and the 16-row tile, pinned here so lavapipe tests them all. Few rows (1, 2, 4) are
  // covered by the small-M shapes above.
  if (!std::string(GetParam()).empty()) GTEST_SKIP() << "texel variants only (run once, in the device instance)";
  const LinearKernel kernels[] = {{8, 2, 1, 2, true}, {8, 2, 2, 2, true}, {16, 2, 0, 2, true}};
  for (const LinearKernel& k : kernels) {
    Options o;
    o.kernel = k;
    o.bias = true;
    o.w_dtype = DType::bf16;
    check(37, 45, 32, o);
    if (k.lanes == 2) {  // the portable path also in its scalar form
      o.kernel->vectorized = false;
      check(37, 45, 19, o);
    }
  }
}

TEST_P(LinearTest, PlainApi) {
  vk::Context& c = ctx();
  std::vector<float> xv = random_values(2 * 3 * 16, 1), wv = random_values(5 * 16, 2), bv = random_values(5, 3);
  Tensor x = Tensor::upload(c, make_host({2, 3, 16}, DType::f32, xv));
  Tensor w = Tensor::upload(c, make_host({5, 16}, DType::bf16, wv));
  Tensor y = Tensor::empty(c, {2, 3, 5}, DType::f32);
  LinearEpilogue ep;
  ep.bias = Tensor::upload(c, make_host({5}, DType::f32, bv));
  ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x, w, y, ep); });
  std::vector<float> got = y.download(c).to_f32();
  for (int r = 0; r < 6; ++r)
    for (int n = 0; n < 5; ++n) {
      double acc = bv[size_t(n)], mag = std::abs(bv[size_t(n)]);
      for (int k = 0; k < 16; ++k) {
        acc += double(xv[size_t(r * 16 + k)]) * wv[size_t(n * 16 + k)];
        mag += std::abs(double(xv[size_t(r * 16 + k)]) * wv[size_t(n * 16 + k)]);
      }
      EXPECT_NEAR(got[size_t(r * 5 + n)], acc, std::max(1e-4, rel_tol() * mag));
    }
  Tensor bad = Tensor::empty(c, {2, 3, 4}, DType::f32);
  EXPECT_THROW(ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x, w, bad, ep); }), Error);
  Tensor wbad = Tensor::empty(c, {5, 15}, DType::f32);
  EXPECT_THROW(ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x, wbad, y, ep); }), Error);
}

// The storage-buffer families on every combination of odd sizes (no multiple of a tile, K not a multiple of
// 4 or 8), then 16-bit weights and the model epilogues on the odd 37 x 45 x 24 / 130 x 129 x 131 shapes.
TEST_P(LinearTest, TiledOddShapeGrid) {
  if (!tiled()) GTEST_SKIP() << "tiled family only (the texel family has its own shape list)";
  for (int64_t m : {1, 7, 37, 130})
    for (int64_t n : {3, 45, 129})
      for (int64_t k : {1, 5, 24, 100, 131}) check(m, n, k, {});
  for (DType dt : {DType::bf16, DType::f16}) {
    Options o;
    o.w_dtype = dt;
    check(37, 45, 24, o);
    check(130, 129, 131, o);
    check(7, 3, 5, o);
  }
}

TEST_P(LinearTest, TiledModelEpilogues) {
  if (!tiled()) GTEST_SKIP() << "tiled family only (Epilogues covers the texel family)";
  Options a;  // CogVideoX FFN up-projection: bias + GELU-tanh, bf16 weight and bias
  a.w_dtype = a.bias_dtype = DType::bf16;
  a.bias = true;
  a.act = Activation::gelu_tanh;
  check(130, 129, 100, a);
  Options g = a;  // gated residual, in place: y += gate ⊙ (xWᵀ + b), the transformer's out projections
  g.act = Activation::none;
  g.gate = g.residual = g.in_place = true;
  g.batch = 2;
  g.per_item_vectors = true;
  check(37, 45, 131, g);
  Options m;  // AdaLN-style modulation with SiLU, f16 weight, f32 bias, unaligned slices everywhere
  m.w_dtype = DType::f16;
  m.bias = true;
  m.act = Activation::silu;
  m.modulation = true;
  m.x_lead = 3;
  m.w_lead = 1;
  m.y_lead = 5;
  check(37, 45, 24, m);
  Options e;  // DINOv2: GELU-erf, f32 weight, padded strides and separate batched weights
  e.bias = true;
  e.act = Activation::gelu_erf;
  e.batch = 3;
  e.shared_weight = false;
  e.x_pad = 3;
  e.y_pad = 2;
  e.residual = true;
  check(7, 129, 5, e);
}

// Activations stored in f16 (what a producer writes where the GEMM runs on tensor cores): the storage families
// read them on both load paths, each weight type, an offset, a padded stride and batches, against the reference on
// the same f16-rounded X; on the tensor-core family the pipelines that ran are the f16-X ones (16-byte loads where
// aligned, element loads at an odd offset). The texel family refuses them by name.
TEST_P(LinearTest, HalfActivations) {
  if (!tiled()) {
    vk::Context& c = ctx();
    Tensor x = Tensor::empty(c, {4, 8}, DType::f16), w = Tensor::empty(c, {3, 8}, DType::f32);
    Tensor y = Tensor::empty(c, {4, 3}, DType::f32);
    test::expect_error([&] { ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x, w, y); }); },
                       {"x must be f32 (or f16 on the tiled and coopmat families)"});
    return;
  }
  vk::Context& c = ctx();
  auto ran_x16 = [&](bool vec) {
    bool found = false;
    c.pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name == "linalg/linear_coopmat" && pl.spec.size() == 15 && pl.spec[10] == (vec ? 1u : 0u) &&
          pl.spec[13] == 1)
        found = true;
    });
    return found;
  };
  const bool coopmat = family() == ops::KernelFamily::coopmat;
  const bool vector_loads = ops::device_tuning(c.caps()).linear_coopmat_vector_loads;
  for (DType wdt : {DType::f16, DType::bf16, DType::f32}) {
    Options o;
    o.x_dtype = DType::f16;
    o.w_dtype = wdt;
    o.bias = true;
    check(37, 45, 48, o);  // aligned: 16-byte loads on the tensor-core family
    if (coopmat) {
      EXPECT_TRUE(ran_x16(vector_loads)) << dtype_name(wdt);
    }
  }
  Options lead;  // 8 halves in: still aligned for 8-value vectors; 3 more: element loads
  lead.x_dtype = DType::f16;
  lead.w_dtype = DType::f16;
  lead.x_lead = 8;
  check(29, 21, 40, lead);
  lead.x_lead = 3;
  check(29, 21, 40, lead);
  if (coopmat) {
    EXPECT_TRUE(ran_x16(false)) << "the misaligned f16 X did not take the element loads";
  }
  Options batched;  // a padded X stride (not a multiple of 8: element loads), batches, modulation and residual
  batched.x_dtype = DType::f16;
  batched.w_dtype = DType::bf16;
  batched.batch = 2;
  batched.x_pad = 3;
  batched.modulation = true;
  batched.residual = true;
  batched.act = Activation::gelu_tanh;
  check(19, 27, 24, batched);
  Options odd;  // K not a multiple of 8
  odd.x_dtype = DType::f16;
  odd.w_dtype = DType::bf16;
  check(13, 11, 21, odd);
}

INSTANTIATE_TEST_SUITE_P(Family, LinearTest, testing::Values("", "linear=tiled"),
                         [](const testing::TestParamInfo<const char*>& i) {
                           return std::string(i.param).empty() ? std::string("device") : std::string("tiled");
                         });

// The tensor-core kernel at other layouts than the tuning's (run where the device has tensor cores and holds
// them: lavapipe 26.1 in the tensor-core pass): one subgroup with K steps of one fragment; 4 x 2 subgroups of
// 1 x 3 fragments (an N tile of three fragments, K 16: 4 rows staged per pass).
INSTANTIATE_TEST_SUITE_P(CoopmatLayout, LinearTest,
                         testing::Values("linear=coopmat,linear_coopmat=1x1x1x1x8",
                                         "linear=coopmat,linear_coopmat=4x2x1x3x16"),
                         [](const testing::TestParamInfo<const char*>& i) {
                           std::string n = std::string(i.param).substr(std::string("linear=coopmat,linear_coopmat=").size());
                           return "layout_" + n;
                         });

}  // namespace
}  // namespace dvs
