// The linear op's test fixture, shared by tests/test_ops_linear.cpp (every family) and
// tests/test_ops_linear_coopmat.cpp (the tensor-core kernel's own paths): random operands, a plain C++ reference
// with double accumulation, and LinearTest, parameterised by a tuning override (the instantiations are in
// test_ops_linear.cpp and cover the TEST_Ps of both files).
// Tolerance: |y - ref| <= 1e-5 * (1 + sum_k |x_k*w_k| + |bias| + |residual| + |shift|) per element (fp32 families;
// 3e-3 on tensor cores) - fp32 accumulation in a different order than the reference, plus fp32 exp in the
// activations. 16-bit operands are compared with a reference that uses the same rounded values.
#pragma once
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "support/gpu.hpp"
#include "support/stored_values.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_linear.hpp"
#include "tensor/tensor.hpp"

namespace dvs::test {

using ops::Activation;
using ops::CoopmatTile;
using ops::LinearEpilogue;
using ops::LinearKernel;
using ops::LinearShape;

inline std::vector<float> random_values(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<float> v(n);
  for (float& f : v) f = u(rng);
  return v;
}

// Host tensor of dtype dt from f32 values; `values` is replaced by what the tensor really holds.
inline HostTensor make_host(Shape s, DType dt, std::vector<float>& values) { return stored_as(values, std::move(s), dt); }

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

inline double activate(double f, Activation a) {
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


}  // namespace dvs::test
