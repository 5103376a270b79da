// Linear / GEMM against a plain C++ reference (double accumulation) on random data.
// Tolerance: |y - ref| ≤ 1e-5 · (1 + Σ_k |x_k·w_k| + |bias| + |residual| + |shift|) per element — fp32
// accumulation in a different order than the reference, plus fp32 exp in the activations. 16-bit weights
// are compared with a reference that uses the same rounded weights, so the tolerance is the same.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <optional>
#include <random>
#include <vector>

#include "support/expect_error.hpp"
#include "support/gpu.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_linear.hpp"
#include "tensor/tensor.hpp"
#include "vk/shader_registry.hpp"

namespace dvs {
namespace {

using ops::Activation;
using ops::LinearEpilogue;
using ops::LinearKernel;
using ops::LinearShape;
using ops::CoopmatTile;

std::vector<float> random_values(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<float> v(n);
  for (float& f : v) f = u(rng);
  return v;
}

// Host tensor of dtype dt from f32 values; `values` is replaced by what the tensor really holds.
HostTensor make_host(Shape s, DType dt, std::vector<float>& values) {
  HostTensor h(s, dt);
  for (size_t i = 0; i < values.size(); ++i) {
    if (dt == DType::f32) {
      h.as<float>()[i] = values[i];
    } else if (dt == DType::bf16) {
      h.as<uint16_t>()[i] = f32_to_bf16(values[i]);
      values[i] = bf16_to_f32(h.as<uint16_t>()[i]);
    } else {
      h.as<uint16_t>()[i] = f32_to_f16(values[i]);
      values[i] = f16_to_f32(h.as<uint16_t>()[i]);
    }
  }
  return h;
}

struct Options {
  DType w_dtype = DType::f32;
  DType x_dtype = DType::f32;  // f16: activations written in 16 bits by their producer (storage families)
  bool bias = false;
  DType bias_dtype = DType::f32;
  Activation act = Activation::none;
  bool modulation = false, gate = false, residual = false;
  bool in_place = false;                 // residual is Y itself
  int64_t batch = 1;
  bool shared_weight = true;             // batch > 1: one W for all items
  bool per_item_vectors = false;         // gate/scale/shift [batch, N]
  int64_t x_lead = 0, w_lead = 0, y_lead = 0;  // elements before the data (unaligned slices)
  int64_t x_pad = 0, y_pad = 0;          // extra row stride beyond K / N
  std::optional<LinearKernel> kernel;
};

double activate(double f, Activation a) {
  if (a == Activation::gelu_tanh) return 0.5 * f * (1 + std::tanh(0.7978845608028654 * (f + 0.044715 * f * f * f)));
  if (a == Activation::silu) return f / (1 + std::exp(-f));
  if (a == Activation::gelu_erf) return 0.5 * f * (1 + std::erf(f / std::sqrt(2.0)));
  return f;
}

// Every test runs for the kernel family the device picks (texel on lavapipe) and for the tiled family
// (storage buffers, shared-memory tiles: what GPUs run) forced with a tuning override.
class LinearTest : public test::GpuTest, public testing::WithParamInterface<const char*> {
 protected:
  void SetUp() override {
    test::GpuTest::SetUp();
    tuning_.emplace(GetParam());
    // The CoopmatLayout instances: other tensor-core layouts, where the device holds them.
    if (std::string(GetParam()).rfind("linear=coopmat", 0) == 0 && family() != ops::KernelFamily::coopmat)
      GTEST_SKIP() << GetParam() << ": " << ops::device_tuning(ctx().caps()).linear_unfit;
  }
  void TearDown() override {
    tuning_.reset();
    test::GpuTest::TearDown();
  }
  bool forced_tiled() const { return std::string(GetParam()) == "linear=tiled"; }
  // The family that runs (the parameter, DVS_TUNING and the device together): tiled() for the storage-buffer
  // families (tiled, coopmat), whatever forced them.
  ops::KernelFamily family() { return ops::device_tuning(ctx().caps()).linear; }
  bool tiled() { return family() != ops::KernelFamily::texel; }
  // Relative to Σ|x·w|: fp32 kernels 1e-5; the tensor-core family rounds x and w to fp16 (2^-11 each), so
  // 3e-3 there (the first H200 run saw 2.2e-4 at most; with 1e-5 every "device" case failed there).
  double rel_tol() { return family() == ops::KernelFamily::coopmat ? 3e-3 : 1e-5; }

  std::optional<ops::ScopedTuningOverride> tuning_;

  // Runs one configuration and compares every element of Y with the reference.
  void check(int64_t M, int64_t N, int64_t K, const Options& o) {
    SCOPED_TRACE(testing::Message() << "M=" << M << " N=" << N << " K=" << K << " w=" << dtype_name(o.w_dtype)
                                    << " batch=" << o.batch);
    vk::Context& c = ctx();
    const int64_t B = o.batch, ldx = K + o.x_pad, ldy = N + o.y_pad;
    const int64_t xbs = M * ldx, ybs = M * ldy, wbs = o.shared_weight ? 0 : N * K, vbs = o.per_item_vectors ? N : 0;
    const int64_t wcount = o.shared_weight ? N * K : B * N * K, vcount = o.per_item_vectors ? B * N : N;
    uint32_t seed = uint32_t(M * 7919 + N * 131 + K);

    std::vector<float> xv = random_values(size_t(o.x_lead + B * xbs), seed + 1);
    std::vector<float> wv = random_values(size_t(o.w_lead + wcount), seed + 2);
    std::vector<float> bv = random_values(size_t(N), seed + 3);
    std::vector<float> sv = random_values(size_t(vcount), seed + 4), hv = random_values(size_t(vcount), seed + 5);
    std::vector<float> gv = random_values(size_t(vcount), seed + 6);
    std::vector<float> rv = random_values(size_t(o.y_lead + B * ybs), seed + 7);

    Tensor xt = Tensor::upload(c, make_host({int64_t(xv.size())}, o.x_dtype, xv));
    Tensor wt = Tensor::upload(c, make_host({int64_t(wv.size())}, o.w_dtype, wv));
    Tensor x = o.x_lead ? xt.rows(o.x_lead, B * xbs) : xt;
    Tensor w = o.w_lead ? wt.rows(o.w_lead, wcount) : wt;
    // Y starts as the residual values (used when in place) or as a NaN-free sentinel.
    std::vector<float> y0(size_t(o.y_lead + B * ybs), 1234.5f);
    if (o.in_place) y0 = rv;
    Tensor yt = Tensor::upload(c, make_host({int64_t(y0.size())}, DType::f32, y0));
    Tensor y = o.y_lead ? yt.rows(o.y_lead, B * ybs) : yt;

    LinearEpilogue ep;
    ep.activation = o.act;
    if (o.bias) ep.bias = Tensor::upload(c, make_host({N}, o.bias_dtype, bv));
    if (o.modulation) {
      ep.scale = Tensor::upload(c, make_host({vcount}, DType::f32, sv));
      ep.shift = Tensor::upload(c, make_host({vcount}, DType::f32, hv));
    }
    if (o.gate) ep.gate = Tensor::upload(c, make_host({vcount}, DType::f32, gv));
    Tensor rt;
    if (o.residual) {
      if (o.in_place) {
        ep.residual = y;
      } else {
        rt = Tensor::upload(c, make_host({int64_t(rv.size())}, DType::f32, rv));
        ep.residual = o.y_lead ? rt.rows(o.y_lead, B * ybs) : rt;
      }
    }
    LinearShape s;
    s.batch = B;
    s.m = M;
    s.n = N;
    s.k = K;
    s.x_batch_stride = xbs;
    s.w_batch_stride = wbs;
    s.y_batch_stride = ybs;
    s.vec_batch_stride = vbs;
    s.x_row_stride = ldx;
    s.y_row_stride = ldy;
    LinearKernel kern = o.kernel ? *o.kernel : ops::choose_linear_kernel(c, s, o.w_dtype);
    if (!o.kernel && forced_tiled()) EXPECT_EQ(kern.family, ops::KernelFamily::tiled);
    ops::run_now(c, [&](vk::Recorder& rec) { ops::linear_batched_with(rec, x, w, y, s, ep, kern); });
    std::vector<float> got = yt.download(c).to_f32();

    int bad = 0;
    for (int64_t b = 0; b < B; ++b)
      for (int64_t m = 0; m < M; ++m)
        for (int64_t n = 0; n < N; ++n) {
          double acc = 0, mag = 1;
          for (int64_t k = 0; k < K; ++k) {
            double p = double(xv[size_t(o.x_lead + b * xbs + m * ldx + k)]) *
                       double(wv[size_t(o.w_lead + b * wbs + n * K + k)]);
            acc += p;
            mag += std::abs(p);
          }
          if (o.bias) {
            acc += bv[size_t(n)];
            mag += std::abs(bv[size_t(n)]);
          }
          acc = activate(acc, o.act);
          size_t v = size_t(b * vbs + n);
          if (o.modulation) {
            acc = acc * (1.0 + sv[v]) + hv[v];
            mag = mag * 2 + std::abs(hv[v]);
          }
          if (o.gate) acc *= gv[v];
          size_t yi = size_t(o.y_lead + b * ybs + m * ldy + n);
          if (o.residual) {
            acc += rv[yi];
            mag += std::abs(rv[yi]);
          }
          double err = std::abs(got[yi] - acc);
          if (!(err <= rel_tol() * mag) && bad++ < 5)
            ADD_FAILURE() << "b=" << b << " m=" << m << " n=" << n << ": got " << got[yi] << ", expected " << acc;
        }
    EXPECT_EQ(bad, 0);
    // Padding between rows and elements outside the view stay untouched.
    if (!o.in_place) {
      for (int64_t b = 0; b < B; ++b)
        for (int64_t m = 0; m < M; ++m)
          for (int64_t n = N; n < ldy; ++n) {
            EXPECT_EQ(got[size_t(o.y_lead + b * ybs + m * ldy + n)], 1234.5f);
          }
      if (o.y_lead) {
        EXPECT_EQ(got[0], 1234.5f);
      }
    }
  }
};

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

// The tensor-core kernel's two load paths and its workgroup order, by value and by the pipeline that ran:
// shapes whose K, strides and offsets are multiples of 8 take the 16-byte loads (each weight type widens its
// own way), an X offset of 3 elements the element loads; M spans 7 tile rows and a part, so bands of 3 tile
// rows end in a partial band (a tile the remapped order missed keeps Y's sentinel, one visited twice is
// harmless but one missed is not). Where the tuning turns the vector loads off, every call takes element loads.
TEST_P(LinearTest, CoopmatLoadPathsAndBands) {
  if (family() != ops::KernelFamily::coopmat) GTEST_SKIP() << "tensor-core family only";
  const std::string base = GetParam();
  ops::ScopedTuningOverride bands(base + (base.empty() ? "" : ",") + "linear_coopmat_group_m=3");
  vk::Context& c = ctx();
  LinearShape probe;
  probe.m = probe.n = probe.k = 8;
  const LinearKernel kern = ops::choose_linear_kernel(c, probe, DType::f32);
  const int64_t M = kern.tile_m * 7 + 5, N = kern.tile_n * 2 + 3;
  // The linear_coopmat pipelines created with bands of 3 and this weight code and load path.
  auto ran = [&](uint32_t wcode, bool vec) {
    bool found = false;
    c.pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name == "linalg/linear_coopmat" && pl.spec.size() == 15 && pl.spec[2] == wcode &&
          pl.spec[10] == (vec ? 1u : 0u) && pl.spec[11] == 3 && pl.spec[12] == 0 && pl.spec[13] == 0)
        found = true;
    });
    return found;
  };
  const bool vector_loads = ops::device_tuning(c.caps()).linear_coopmat_vector_loads;
  const std::pair<DType, uint32_t> types[] = {{DType::f32, 0}, {DType::f16, 1}, {DType::bf16, 2}};
  for (const auto& [dt, code] : types) {
    Options o;
    o.w_dtype = dt;
    o.bias = true;
    check(M, N, 48, o);
    EXPECT_TRUE(ran(code, vector_loads)) << dtype_name(dt) << ": the aligned call did not take the expected path";
  }
  Options u;
  u.w_dtype = DType::bf16;
  u.x_lead = 3;
  check(M, N, 48, u);
  EXPECT_TRUE(ran(2, false)) << "the misaligned call did not take the element loads";
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

// Y stored f16 by the tensor-core kernel (the FFN's GELU output, the next GEMM's X): each value the f32 Y of the
// same call rounded to nearest even, bit for bit, written in pairs into a padded, batched view at an offset (the
// padding and the elements around the view stay untouched); refused where a pair could straddle a row (odd N),
// with a residual, and on the other families.
TEST_P(LinearTest, CoopmatHalfOutputs) {
  if (family() != ops::KernelFamily::coopmat) GTEST_SKIP() << "tensor-core family only";
  vk::Context& c = ctx();
  const int64_t B = 2, M = 37, N = 46, K = 48, ldy = N + 2, lead = 6;
  std::vector<float> xv = random_values(size_t(B * M * K), 5), wv = random_values(size_t(N * K), 6),
                     bv = random_values(size_t(N), 7);
  Tensor x = Tensor::upload(c, make_host({B * M * K}, DType::f16, xv));
  Tensor w = Tensor::upload(c, make_host({N, K}, DType::bf16, wv));
  LinearEpilogue ep;
  ep.bias = Tensor::upload(c, make_host({N}, DType::f32, bv));
  ep.activation = Activation::gelu_tanh;
  LinearShape s;
  s.batch = B, s.m = M, s.n = N, s.k = K, s.x_batch_stride = M * K, s.y_batch_stride = M * ldy, s.y_row_stride = ldy;
  Tensor y32 = Tensor::empty(c, {B * M * ldy}, DType::f32);
  Tensor big = Tensor::zeros(c, {lead + B * M * ldy + 4}, DType::f16);
  Tensor y16 = big.rows(lead, B * M * ldy);
  ops::run_now(c, [&](vk::Recorder& rec) {
    ops::linear_batched(rec, x, w, y32, s, ep);
    ops::linear_batched(rec, x, w, y16, s, ep);
  });
  const std::vector<float> f = y32.download(c).to_f32();
  const HostTensor h = big.download(c);
  size_t differ = 0, touched = 0;
  for (int64_t i = 0; i < int64_t(h.numel()); ++i) {
    const int64_t o = i - lead, col = o % ldy;
    const bool inside = o >= 0 && o < B * M * ldy && col < N;
    if (inside) differ += h.as<uint16_t>()[size_t(i)] != f32_to_f16(f[size_t(o)]);
    else touched += h.as<uint16_t>()[size_t(i)] != 0;
  }
  EXPECT_EQ(differ, 0u) << "f16 outputs that are not the f32 ones rounded";
  EXPECT_EQ(touched, 0u) << "writes outside the view or into the padding";

  std::vector<float> wodd_v(wv.begin(), wv.begin() + (N - 1) * K);
  Tensor odd = Tensor::empty(c, {M, N - 1}, DType::f16), wodd = Tensor::upload(c, make_host({N - 1, K}, DType::f32, wodd_v));
  const Tensor x2 = x.rows(0, M * K).reshape({M, K});
  test::expect_error([&] { ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x2, wodd, odd); }); },
                     {"an f16 y needs the coopmat family, N and y's strides even and no residual"});
  Tensor ye = Tensor::zeros(c, {M, N}, DType::f16);
  test::expect_error([&] {
    ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x2, w, ye, LinearEpilogue{.residual = ye}); });
  }, {"no residual"});
  ops::ScopedTuningOverride tiled("linear=tiled");
  test::expect_error([&] { ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x2, w, ye); }); },
                     {"an f16 y needs the coopmat family"});
}

// The per-shape tile table by value: a call with N >= 40 takes row 1's layout, one with M <= 20 (and N under 40)
// row 2's, the others the tuning's linear_coopmat, each checked against the reference and by the pipeline that ran
// (its layout's specialization constants).
TEST_P(LinearTest, CoopmatPerShapeTiles) {
  if (family() != ops::KernelFamily::coopmat) GTEST_SKIP() << "tensor-core family only";
  const std::string base = GetParam();
  ops::ScopedTuningOverride rows(base + (base.empty() ? "" : ",") +
                                 "linear_coopmat_by_shape=n>=40:1x1x1x1x8+m<=20:4x2x1x3x16");
  vk::Context& c = ctx();
  const CoopmatTile fallback = ops::device_tuning(c.caps()).linear_coopmat;
  auto ran = [&](const CoopmatTile& t) {
    bool found = false;
    c.pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name == "linalg/linear_coopmat" && pl.spec.size() == 15 && pl.spec[0] == uint32_t(t.sg_m) &&
          pl.spec[1] == uint32_t(t.sg_n) && pl.spec[3] == uint32_t(t.k) && pl.spec[5] == uint32_t(t.frags_m) &&
          pl.spec[6] == uint32_t(t.frags_n))
        found = true;
    });
    return found;
  };
  const struct {
    int64_t m, n, k;
    CoopmatTile tile;
  } cases[] = {{37, 45, 48, {1, 1, 1, 1, 8}}, {19, 24, 40, {4, 2, 1, 3, 16}}, {37, 24, 48, fallback}};
  for (const auto& k : cases) {
    LinearShape s;
    s.m = k.m, s.n = k.n, s.k = k.k;
    const LinearKernel kern = ops::choose_linear_kernel(c, s, DType::bf16);
    EXPECT_EQ(kern.coopmat.sg_m, k.tile.sg_m) << k.m << "x" << k.n;
    EXPECT_EQ(kern.coopmat.frags_n, k.tile.frags_n) << k.m << "x" << k.n;
    Options o;
    o.w_dtype = DType::bf16;
    o.bias = true;
    check(k.m, k.n, k.k, o);
    EXPECT_TRUE(ran(k.tile)) << k.m << "x" << k.n << ": its layout's pipeline did not run";
  }
}

// The ablations the device script's sweep times (measurements only) are live: without MMA an aligned call's Y
// is its bias alone; without global loads Y no longer depends on X (two different X give the same Y).
TEST_P(LinearTest, CoopmatAblationsAreLive) {
  if (family() != ops::KernelFamily::coopmat) GTEST_SKIP() << "tensor-core family only";
  const std::string base = GetParam();
  vk::Context& c = ctx();
  const int64_t M = 37, N = 45, K = 48;
  auto run = [&](const char* ablation, uint32_t seed) {
    ops::ScopedTuningOverride t(base + (base.empty() ? "" : ",") + "linear_coopmat_ablation=" + ablation);
    std::vector<float> xv = random_values(size_t(M * K), seed), wv = random_values(size_t(N * K), 2),
                       bv = random_values(size_t(N), 3);
    Tensor x = Tensor::upload(c, make_host({M, K}, DType::f32, xv));
    Tensor w = Tensor::upload(c, make_host({N, K}, DType::bf16, wv));
    Tensor y = Tensor::empty(c, {M, N}, DType::f32);
    LinearEpilogue ep;
    ep.bias = Tensor::upload(c, make_host({N}, DType::f32, bv));
    ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x, w, y, ep); });
    return std::make_pair(y.download(c).to_f32(), bv);
  };
  const auto [no_mma, bias] = run("no_mma", 1);
  for (int64_t m = 0; m < M; ++m)
    for (int64_t n = 0; n < N; ++n) ASSERT_EQ(no_mma[size_t(m * N + n)], bias[size_t(n)]) << m << "," << n;
  EXPECT_EQ(run("no_global_loads", 1).first, run("no_global_loads", 7).first);
  EXPECT_NE(run("none", 1).first, run("none", 7).first);
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

// The tensor-core kernel cannot run on lavapipe (no VK_KHR_cooperative_matrix): it is embedded (compiled by
// glslang 15 and checked by spirv-val at build time), and asking for it on a device without a coopmat shape
// runs the tiled kernel instead.
class LinearCoopmatTest : public test::GpuTest {};

TEST_F(LinearCoopmatTest, ShadersEmbedded) {
  const std::vector<std::string> names = vk::shader_names();
  for (const char* want : {"linalg/linear_coopmat", "linalg/linear_tiled", "bench/coopmat_mma_rate"})
    EXPECT_NE(std::find(names.begin(), names.end(), want), names.end()) << want;
}

TEST_F(LinearCoopmatTest, FallsBackToTiledWithoutCoopmat) {
  vk::Context& c = ctx();
  if (ops::device_tuning(c.caps()).coopmat.defined()) GTEST_SKIP() << "the device has cooperative matrices";
  LinearShape s;
  s.m = 37;
  s.n = 45;
  s.k = 24;
  for (const char* o : {"linear=coopmat", "gpu-coopmat"}) {
    ops::ScopedTuningOverride t(o);
    const LinearKernel k = ops::choose_linear_kernel(c, s, DType::bf16);
    EXPECT_EQ(k.family, ops::KernelFamily::tiled) << o;
  }
  {
    // The tiled kernel caps its tile at 64x64 (8x8 register blocks did not finish on the H100).
    ops::ScopedTuningOverride big("linear=tiled,linear_tile_m=128,linear_tile_n=128,linear_tile_k=32");
    const LinearKernel k = ops::choose_linear_kernel(c, s, DType::f32);
    EXPECT_EQ(k.tile_m, 64);
    EXPECT_EQ(k.tile_n, 64);
    EXPECT_EQ(k.tile_k, 16);
  }
  ops::ScopedTuningOverride t("gpu-coopmat");
  // And it runs: y = x·wᵀ on the tiled kernel.
  std::vector<float> xv = random_values(37 * 24, 1), wv = random_values(45 * 24, 2);
  Tensor x = Tensor::upload(c, make_host({37, 24}, DType::f32, xv));
  Tensor w = Tensor::upload(c, make_host({45, 24}, DType::bf16, wv));
  Tensor y = Tensor::empty(c, {37, 45}, DType::f32);
  LinearEpilogue ep;
  ep.fp16_operands_ok = false;
  ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x, w, y, ep); });
  std::vector<float> got = y.download(c).to_f32();
  for (int m = 0; m < 37; ++m)
    for (int n = 0; n < 45; ++n) {
      double acc = 0;
      for (int kk = 0; kk < 24; ++kk) acc += double(xv[size_t(m * 24 + kk)]) * wv[size_t(n * 24 + kk)];
      EXPECT_NEAR(got[size_t(m * 45 + n)], acc, 1e-4);
    }
}

}  // namespace
}  // namespace dvs
