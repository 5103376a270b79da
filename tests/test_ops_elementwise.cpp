// Elementwise ops and casts against plain C++ references (double arithmetic), on odd sizes (scalar paths)
// and multiples of 4 (vec4 paths), with every broadcast kind and in place.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <vector>

#include "support/gpu.hpp"
#include "support/texel_paths.hpp"
#include "support/scoped_limits.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"

namespace dvs {
namespace {

class ElementwiseOps : public test::GpuTest {};

// The f32 ops run twice: with texel-buffer inputs (the default where views allow) and forced onto the
// storage-buffer shaders, so both variants of every op are checked.
class ElementwiseOpsPaths : public test::TexelPathsTest {};
DVS_TEXEL_PATHS(ElementwiseOps, ElementwiseOpsPaths);

std::vector<float> random_values(int64_t n, uint32_t seed, float lo = -4.0f, float hi = 4.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(lo, hi);
  std::vector<float> v(static_cast<size_t>(n));
  for (float& x : v) x = d(rng);
  return v;
}

Tensor upload(vk::Context& ctx, const Shape& s, const std::vector<float>& v) {
  return Tensor::upload(ctx, HostTensor::from_f32(s, v));
}

// Odd sizes exercise the scalar shaders, multiples of 4 the vec4 ones; [2, 13, 16, 60/8...] the tiny model.
// {3, 5, 67}: odd and large enough for a vec4 body plus a scalar tail.
const std::vector<Shape> kShapes = {{1}, {7}, {33}, {129}, {3, 5, 7}, {3, 5, 67}, {4, 8}, {2, 16, 6, 10}, {1, 2, 16, 30, 45}};

void expect_close(const std::vector<float>& got, const std::vector<double>& want, double atol, double rtol,
                  const std::string& what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  for (size_t i = 0; i < got.size(); ++i)
    ASSERT_NEAR(got[i], want[i], atol + rtol * std::fabs(want[i])) << what << " at " << i;
}

struct UnaryCase {
  const char* name;
  std::function<void(vk::Recorder&, const Tensor&, const Tensor&)> op;
  std::function<double(double)> ref;
  double atol, rtol;
};

TEST_P(ElementwiseOpsPaths, UnaryOpsMatchReference) {
  const double k = std::sqrt(2.0 / M_PI);
  // Tolerances: affine/clamp are one fp32 rounding (or exact); SiLU and GELU go through the device's exp
  // (a few ulp) and, for GELU, a division: 2e-6 absolute + 1e-5 relative.
  std::vector<UnaryCase> cases = {
      {"scale", [](vk::Recorder& r, const Tensor& x, const Tensor& y) { ops::scale(r, x, y, 0.7f, -0.25f); },
       [](double v) { return double(0.7f) * v - 0.25; }, 1e-6, 1e-6},
      {"silu", [](vk::Recorder& r, const Tensor& x, const Tensor& y) { ops::silu(r, x, y); },
       [](double v) { return v / (1.0 + std::exp(-v)); }, 2e-6, 1e-5},
      {"gelu_tanh", [](vk::Recorder& r, const Tensor& x, const Tensor& y) { ops::gelu_tanh(r, x, y); },
       [k](double v) { return 0.5 * v * (1.0 + std::tanh(k * (v + 0.044715 * v * v * v))); }, 2e-6, 1e-5},
      {"clamp", [](vk::Recorder& r, const Tensor& x, const Tensor& y) { ops::clamp(r, x, y, -1.5f, 2.25f); },
       [](double v) { return std::clamp(v, -1.5, 2.25); }, 0, 0},
      // erf has no GLSL built-in: the shader's fitted erfc is good to ~1.2e-7 relative.
      {"gelu_erf", [](vk::Recorder& r, const Tensor& x, const Tensor& y) { ops::gelu_erf(r, x, y); },
       [](double v) { return 0.5 * v * (1.0 + std::erf(v / std::sqrt(2.0))); }, 2e-6, 1e-5},
      {"relu", [](vk::Recorder& r, const Tensor& x, const Tensor& y) { ops::relu(r, x, y); },
       [](double v) { return std::max(v, 0.0); }, 0, 0},
  };
  uint32_t seed = 1;
  for (const UnaryCase& c : cases) {
    for (const Shape& s : kShapes) {
      auto x = random_values(shape_numel(s), seed++, -12.0f, 12.0f);
      if (x.size() > 4) {  // the tails where naive formulas overflow
        x[0] = -100.0f;
        x[1] = 100.0f;
        x[2] = 0.0f;
        x[3] = -1e-30f;
      }
      Tensor tx = upload(ctx(), s, x), ty = Tensor::empty(ctx(), s, DType::f32);
      ops::run_now(ctx(), [&](vk::Recorder& r) { c.op(r, tx, ty); });
      std::vector<double> want(x.size());
      for (size_t i = 0; i < x.size(); ++i) want[i] = c.ref(x[i]);
      expect_close(ty.download(ctx()).to_f32(), want, c.atol, c.rtol, std::string(c.name) + " [" + shape_str(s) + "]");
      // In place gives the same values.
      ops::run_now(ctx(), [&](vk::Recorder& r) { c.op(r, tx, tx); });
      expect_close(tx.download(ctx()).to_f32(), want, c.atol, c.rtol, std::string(c.name) + " in place");
    }
  }
}

struct BroadcastCase {
  Shape x, y;
  std::function<size_t(size_t)> y_index;  // element of y used for element e of x
};

TEST_P(ElementwiseOpsPaths, BinaryOpsBroadcastMatchReference) {
  std::vector<BroadcastCase> cases = {
      {{7}, {7}, [](size_t e) { return e; }},
      {{3, 5, 7}, {3, 5, 7}, [](size_t e) { return e; }},
      {{2, 16, 6, 10}, {2, 16, 6, 10}, [](size_t e) { return e; }},
      {{33}, {}, [](size_t) { return size_t(0); }},
      {{4, 8}, {1}, [](size_t) { return size_t(0); }},
      {{5, 7}, {7}, [](size_t e) { return e % 7; }},          // row vector, scalar path
      {{9, 12}, {12}, [](size_t e) { return e % 12; }},       // row vector, vec4 path
      {{6, 10}, {1, 10}, [](size_t e) { return e % 10; }},    // row vector, gathered per component
      {{2, 3, 5, 7}, {3, 1, 1}, [](size_t e) { return (e / 35) % 3; }},        // per channel, odd inner
      {{2, 16, 6, 10}, {16, 1, 1}, [](size_t e) { return (e / 60) % 16; }},    // per channel, inner % 4 == 0
      {{1, 2, 16, 3, 3}, {1, 1, 16, 1, 1}, [](size_t e) { return (e / 9) % 16; }},
      {{2, 3, 4, 5}, {3, 4, 1}, [](size_t e) { return (e / 5) % 12; }},        // run of two axes
  };
  uint32_t seed = 100;
  for (const BroadcastCase& c : cases) {
    const int64_t n = shape_numel(c.x);
    auto x = random_values(n, seed++), y = random_values(shape_numel(c.y), seed++);
    Tensor tx = upload(ctx(), c.x, x), ty = upload(ctx(), c.y, y), tz = Tensor::empty(ctx(), c.x, DType::f32);
    const std::string where = "[" + shape_str(c.x) + "] op [" + shape_str(c.y) + "]";
    // Tolerance: one or two fp32 roundings: 1e-6 absolute + 1e-6 relative.
    auto check = [&](const char* name, auto op, auto ref) {
      ops::run_now(ctx(), [&](vk::Recorder& r) { op(r, tx, ty, tz); });
      std::vector<double> want(static_cast<size_t>(n));
      for (size_t e = 0; e < size_t(n); ++e) want[e] = ref(double(x[e]), double(y[c.y_index(e)]));
      expect_close(tz.download(ctx()).to_f32(), want, 1e-6, 1e-6, std::string(name) + " " + where);
    };
    check("add", [](vk::Recorder& r, auto& a, auto& b, auto& z) { ops::add(r, a, b, z); },
          [](double a, double b) { return a + b; });
    check("sub", [](vk::Recorder& r, auto& a, auto& b, auto& z) { ops::sub(r, a, b, z); },
          [](double a, double b) { return a - b; });
    check("mul", [](vk::Recorder& r, auto& a, auto& b, auto& z) { ops::mul(r, a, b, z); },
          [](double a, double b) { return a * b; });
    check("axpby", [](vk::Recorder& r, auto& a, auto& b, auto& z) { ops::axpby(r, 0.75f, a, -1.5f, b, z); },
          [](double a, double b) { return 0.75 * a - 1.5 * b; });
  }
}

TEST_P(ElementwiseOpsPaths, ScaleShiftBroadcasts) {
  // z = x·(s + offset) + t; tolerance 1e-6 absolute + 1e-6 relative (one rounding more or less: FMA or not).
  struct Case {
    Shape x, st;
    std::function<size_t(size_t)> idx;
    float offset;
  };
  std::vector<Case> cases = {
      {{2, 16, 6, 10}, {16, 1, 1}, [](size_t e) { return (e / 60) % 16; }, 0.0f},   // AdaIN per channel
      {{2, 3, 5, 7}, {3, 1, 1}, [](size_t e) { return (e / 35) % 3; }, 0.0f},       // odd sizes
      {{35, 12}, {12}, [](size_t e) { return e % 12; }, 1.0f},                      // adaLN rows, 1 + scale
      {{33, 7}, {7}, [](size_t e) { return e % 7; }, 1.0f},
      {{129}, {129}, [](size_t e) { return e; }, 0.0f},                             // same shape
      {{8}, {}, [](size_t) { return size_t(0); }, 0.5f},                            // scalar
  };
  uint32_t seed = 300;
  for (const Case& c : cases) {
    const int64_t n = shape_numel(c.x), m = shape_numel(c.st);
    auto x = random_values(n, seed++), sv = random_values(m, seed++), tv = random_values(m, seed++);
    Tensor tx = upload(ctx(), c.x, x), ts = upload(ctx(), c.st, sv), tt = upload(ctx(), c.st, tv);
    Tensor tz = Tensor::empty(ctx(), c.x, DType::f32);
    ops::run_now(ctx(), [&](vk::Recorder& r) { ops::scale_shift(r, tx, ts, tt, tz, c.offset); });
    std::vector<double> want(static_cast<size_t>(n));
    for (size_t e = 0; e < want.size(); ++e)
      want[e] = double(x[e]) * (double(sv[c.idx(e)]) + c.offset) + double(tv[c.idx(e)]);
    expect_close(tz.download(ctx()).to_f32(), want, 1e-6, 1e-6, "scale_shift [" + shape_str(c.x) + "]");
    ops::run_now(ctx(), [&](vk::Recorder& r) { ops::scale_shift(r, tx, ts, tt, tx, c.offset); });  // in place
    expect_close(tx.download(ctx()).to_f32(), want, 1e-6, 1e-6, "scale_shift in place");
  }
}

TEST_P(ElementwiseOpsPaths, BroadcastAcrossGridStrides) {
  // > 4096·64 vec4s, so every invocation loops and the incremental (channel, inner) counters advance: one
  // case per broadcast mode of shaders/nn/eltwise_broadcast.glsl. Tolerance 1e-6 abs + 1e-6 rel.
  std::vector<BroadcastCase> cases = {
      {{1200012}, {1200012}, [](size_t e) { return e; }},                          // same shape
      {{1100, 1024}, {1024}, [](size_t e) { return e % 1024; }},                    // rows, C % 4 == 0
      {{3, 16, 25000}, {16, 1}, [](size_t e) { return (e / 25000) % 16; }},         // channels, inner % 4 == 0
      {{4, 3, 100001}, {3, 1}, [](size_t e) { return (e / 100001) % 3; }},          // channels, odd inner
      {{171432, 7}, {7}, [](size_t e) { return e % 7; }},                           // rows, C % 4 != 0
      {{200002, 3, 2}, {3, 1}, [](size_t e) { return (e / 2) % 3; }},               // inner 2: general
  };
  uint32_t seed = 500;
  for (const BroadcastCase& c : cases) {
    const int64_t n = shape_numel(c.x), m = shape_numel(c.y);
    if (test::over_allocation_limit(ctx(), uint64_t(n) * 4, "broadcast [" + shape_str(c.x) + "]")) continue;
    auto x = random_values(n, seed++), y = random_values(m, seed++), t = random_values(m, seed++);
    Tensor tx = upload(ctx(), c.x, x), ty = upload(ctx(), c.y, y), tt = upload(ctx(), c.y, t);
    Tensor tz = Tensor::empty(ctx(), c.x, DType::f32), tw = Tensor::empty(ctx(), c.x, DType::f32);
    ops::run_now(ctx(), [&](vk::Recorder& r) {
      ops::axpby(r, 0.5f, tx, 2.0f, ty, tz);
      ops::scale_shift(r, tx, ty, tt, tw, 1.0f);
    });
    std::vector<double> want(static_cast<size_t>(n)), want2(static_cast<size_t>(n));
    for (size_t e = 0; e < want.size(); ++e) {
      const size_t j = c.y_index(e);
      want[e] = 0.5 * x[e] + 2.0 * y[j];
      want2[e] = double(x[e]) * (double(y[j]) + 1.0) + double(t[j]);
    }
    const std::string where = "[" + shape_str(c.x) + "] by [" + shape_str(c.y) + "]";
    expect_close(tz.download(ctx()).to_f32(), want, 1e-6, 1e-6, "axpby " + where);
    expect_close(tw.download(ctx()).to_f32(), want2, 1e-6, 1e-6, "scale_shift " + where);
  }
}

TEST_P(ElementwiseOpsPaths, BinaryOpsInPlaceAndErrors) {
  auto x = random_values(129, 7), y = random_values(129, 8);
  Tensor tx = upload(ctx(), {129}, x), ty = upload(ctx(), {129}, y);
  ops::run_now(ctx(), [&](vk::Recorder& r) { ops::axpby(r, 2.0f, tx, 3.0f, ty, tx); });  // x = 2x + 3y
  std::vector<double> want(129);
  for (size_t i = 0; i < 129; ++i) want[i] = 2.0 * x[i] + 3.0 * y[i];
  expect_close(tx.download(ctx()).to_f32(), want, 1e-6, 1e-6, "axpby in place");
  ops::run_now(ctx(), [&](vk::Recorder& r) { ops::mul(r, ty, ty, ty); });  // y = y²
  for (size_t i = 0; i < 129; ++i) want[i] = double(y[i]) * y[i];
  expect_close(ty.download(ctx()).to_f32(), want, 1e-6, 1e-6, "square in place");

  Tensor a = Tensor::empty(ctx(), {4, 6}, DType::f32), bad = Tensor::empty(ctx(), {4}, DType::f32);
  Tensor gap = Tensor::empty(ctx(), {4, 1, 6}, DType::f32), a3 = Tensor::empty(ctx(), {4, 5, 6}, DType::f32);
  auto rec = [&](auto f) { ops::run_now(ctx(), f); };
  EXPECT_THROW(rec([&](vk::Recorder& r) { ops::add(r, a, bad, a); }), Error);  // [4] does not match D = 6
  EXPECT_THROW(rec([&](vk::Recorder& r) { ops::add(r, a3, gap, a3); }), Error);  // non-contiguous run of axes
  EXPECT_THROW(rec([&](vk::Recorder& r) { ops::add(r, a, a, bad); }), Error);  // wrong output shape
  Tensor i = Tensor::empty(ctx(), {4, 6}, DType::i32);
  EXPECT_THROW(rec([&](vk::Recorder& r) { ops::silu(r, i, i); }), Error);
  EXPECT_THROW(rec([&](vk::Recorder& r) { ops::clamp(r, a, a, 1.0f, 0.0f); }), Error);
}

TEST_F(ElementwiseOps, CastsRoundToNearestEven) {
  // Values chosen around every rounding case: ties to even, f16 overflow (65504 / 65520), f16 subnormals
  // and the 2^-25 boundary, NaN, ±Inf, ±0, plus random values over a wide exponent range.
  std::vector<float> special = {0.0f, -0.0f, 1.0f, -1.0f, 65504.0f, 65519.99f, 65520.0f, -70000.0f,
                                std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                                std::numeric_limits<float>::quiet_NaN(), 0x1p-14f, 0x1p-24f, 0x1p-25f,
                                0x1.000002p-25f, 0x1.8p-24f, 0x1.4p-20f, 1.0f + 0x1p-11f, 1.0f + 0x3p-11f,
                                1.0f + 0x1p-8f, 1.0f + 0x3p-8f, 3.4e38f, 1e-40f, 0x1.fffffep-15f, 6.1e-5f};
  for (int64_t n : {1, 2, 7, 33, 130, 1001, 32, 1024}) {  // the last two: 8 per step
    std::vector<float> v = random_values(n, uint32_t(n), -1.0f, 1.0f);
    std::mt19937 rng(uint32_t(n) + 5);
    for (float& x : v) x = std::ldexp(x, int(rng() % 40) - 28);
    for (size_t i = 0; i < v.size() && i < special.size(); ++i) v[i] = special[i];
    Tensor f = upload(ctx(), {n}, v);
    for (DType dt : {DType::bf16, DType::f16}) {
      // The narrowing is exact integer arithmetic: compared bit for bit with the host conversion.
      // The neighbour after an odd-length 16-bit tensor is a separate allocation here; its bytes survive.
      Tensor h = Tensor::empty(ctx(), {n}, dt), back = Tensor::empty(ctx(), {n}, DType::f32);
      ops::run_now(ctx(), [&](vk::Recorder& r) {
        ops::cast(r, f, h);
        ops::cast(r, h, back);
      });
      HostTensor hh = h.download(ctx());
      auto wide = back.download(ctx()).to_f32();
      for (int64_t i = 0; i < n; ++i) {
        uint16_t want = dt == DType::bf16 ? f32_to_bf16(v[size_t(i)]) : f32_to_f16(v[size_t(i)]);
        uint16_t got = hh.as<uint16_t>()[i];
        ASSERT_EQ(got, want) << dtype_name(dt) << " n=" << n << " i=" << i << " v=" << v[size_t(i)];
        float w = dt == DType::bf16 ? bf16_to_f32(want) : f16_to_f32(want);
        if (std::isnan(w)) ASSERT_TRUE(std::isnan(wide[size_t(i)]));
        else ASSERT_EQ(std::bit_cast<uint32_t>(wide[size_t(i)]), std::bit_cast<uint32_t>(w)) << "widen i=" << i;
      }
    }
  }
}

TEST_F(ElementwiseOps, CastOddHalfKeepsNeighbour) {
  // A 3-element bf16 tensor inside a larger one: the 4th element shares the last word and must survive.
  Tensor big = Tensor::empty(ctx(), {4}, DType::bf16);
  HostTensor init({4}, DType::bf16);
  for (int i = 0; i < 4; ++i) init.as<uint16_t>()[i] = 0xABCD;
  big.write(ctx(), init);
  Tensor part = Tensor::on(big.buffer(), {3}, DType::bf16);
  Tensor src = upload(ctx(), {3}, {1.0f, 2.0f, 3.0f});
  ops::run_now(ctx(), [&](vk::Recorder& r) { ops::cast(r, src, part); });
  HostTensor got = big.download(ctx());
  EXPECT_EQ(got.as<uint16_t>()[0], f32_to_bf16(1.0f));
  EXPECT_EQ(got.as<uint16_t>()[2], f32_to_bf16(3.0f));
  EXPECT_EQ(got.as<uint16_t>()[3], 0xABCD);
}

TEST_F(ElementwiseOps, CastIntegers) {
  // Saturation at the largest floats inside the int32 range; 7 elements run two per step, 8 eight per step.
  std::vector<float> v8 = {0.0f, 1.9f, -1.9f, 1e10f, -1e10f, std::numeric_limits<float>::quiet_NaN(), 123456.0f, -7.5f};
  std::vector<int32_t> want8 = {0, 1, -1, INT32_MAX - 127, INT32_MIN, 0, 123456, -7};
  for (int64_t n : {7, 8}) {
    std::vector<float> v(v8.begin(), v8.begin() + n);
    Tensor f = upload(ctx(), {n}, v), i = Tensor::empty(ctx(), {n}, DType::i32), back = Tensor::empty(ctx(), {n}, DType::f32);
    ops::run_now(ctx(), [&](vk::Recorder& r) {
      ops::cast(r, f, i);
      ops::cast(r, i, back);
    });
    HostTensor hi = i.download(ctx());
    auto b = back.download(ctx()).to_f32();
    for (size_t k = 0; k < size_t(n); ++k) {
      EXPECT_EQ(hi.as<int32_t>()[k], want8[k]) << k;
      EXPECT_EQ(b[k], float(want8[k])) << k;
    }
  }
  // 16-bit to 16-bit goes through f32 exactly: bf16 -> f16 -> bf16 of small integers is the identity.
  for (int64_t n : {5, 16}) {
    HostTensor h({n}, DType::bf16);
    for (int64_t k = 0; k < n; ++k) h.as<uint16_t>()[k] = f32_to_bf16(float(k) - 3.0f);
    Tensor a = Tensor::upload(ctx(), h), m = Tensor::empty(ctx(), {n}, DType::f16), c = Tensor::empty(ctx(), {n}, DType::bf16);
    ops::run_now(ctx(), [&](vk::Recorder& r) {
      ops::cast(r, a, m);
      ops::cast(r, m, c);
    });
    HostTensor hm = m.download(ctx()), hc = c.download(ctx());
    for (int64_t k = 0; k < n; ++k) {
      EXPECT_EQ(hm.as<uint16_t>()[k], f32_to_f16(float(k) - 3.0f));
      EXPECT_EQ(hc.as<uint16_t>()[k], h.as<uint16_t>()[k]);
    }
  }
}

}  // namespace
}  // namespace dvs
