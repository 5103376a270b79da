// Positional ops: CogVideoX 3D RoPE tables (host builder vs the golden pack and hand-checked entries), RoPE
// application on token slices of fused buffers, and the sinusoidal timestep embedding, against C++
// references.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "io/npy.hpp"
#include "support/gpu.hpp"
#include "tensor/ops_position.hpp"

namespace dvs {
namespace {

using test::GpuTest;
using PositionOps = GpuTest;  // the suite name selects these for the DVS_TUNING=gpu pass

std::vector<float> random_values(size_t n, uint32_t seed, float lo = -2.0f, float hi = 2.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dist(lo, hi);
  std::vector<float> v(n);
  for (float& x : v) x = dist(rng);
  return v;
}

double max_abs_diff(const std::vector<float>& a, const std::vector<float>& b) {
  EXPECT_EQ(a.size(), b.size());
  double m = 0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    double d = std::abs(double(a[i]) - double(b[i]));
    if (!(d <= m)) m = d;  // NaN wins
  }
  return m;
}

// ---------------------------------------------------------------- RoPE tables
// Tolerance: 1e-6 absolute (cos/sin of the same fp32 arguments; libm vs torch differ by an ulp at most).
TEST(RopeTables, MatchGoldenPack) {
  std::filesystem::path dir = std::filesystem::path(test::golden_dir()) / "transformer";
  HostTensor gc = read_npy(dir / "rope_cos.npy"), gs = read_npy(dir / "rope_sin.npy");
  // Pack args: height 64, width 64, 3 latent frames; transformer config: patch 2, sample 8x8, head_dim 16.
  ops::RopeTables t = ops::cogvideox_rope_tables_for_video(64, 64, 3, 8, 2, 8, 8, 16);
  ASSERT_EQ(t.cos.shape, gc.shape);
  ASSERT_EQ(t.sin.shape, gs.shape);
  EXPECT_LE(max_abs_diff(t.cos.to_f32(), gc.to_f32()), 1e-6);
  EXPECT_LE(max_abs_diff(t.sin.to_f32(), gs.to_f32()), 1e-6);
}

TEST(RopeTables, RealModelGridByHand) {
  // CogVideoX-5B-I2V at 480x720, 13 latent frames: 30x45 tokens per frame, base size 30x45 (sample 60x90 / 2),
  // so the crop is the whole grid and positions are 0, 1, 2, ... on every axis.
  ops::RopeTables t = ops::cogvideox_rope_tables_for_video(480, 720, 13, 8, 2, 60, 90, 64);
  ASSERT_EQ(t.cos.shape, (Shape{13 * 30 * 45, 64}));
  const int64_t f = 5, y = 7, x = 11, row = (f * 30 + y) * 45 + x;
  const float* c = t.cos.as<float>() + row * 64;
  const float* s = t.sin.as<float>() + row * 64;
  auto freq = [](int j, int dim) { return 1.0 / std::pow(10000.0, double(2 * j) / dim); };
  for (int j = 0; j < 8; ++j) {  // t: 16 columns, 8 frequencies
    EXPECT_NEAR(c[2 * j], std::cos(f * freq(j, 16)), 2e-6);
    EXPECT_EQ(c[2 * j], c[2 * j + 1]);
  }
  for (int j = 0; j < 12; ++j) {  // h, w: 24 columns each
    EXPECT_NEAR(s[16 + 2 * j], std::sin(y * freq(j, 24)), 2e-6);
    EXPECT_NEAR(s[40 + 2 * j + 1], std::sin(x * freq(j, 24)), 2e-6);
  }
  // A smaller, non-square video is cropped inside the base grid: 240x480 -> 15x30 tokens in a 30x45 base:
  // h/w = 0.5 < 30/45, so resize width 45, height round(45/30*15) = 22 (22.5 rounds to even), top round(4) = 4.
  ops::RopeTables u = ops::cogvideox_rope_tables_for_video(240, 480, 2, 8, 2, 60, 90, 64);
  ASSERT_EQ(u.cos.shape, (Shape{2 * 15 * 30, 64}));
  // Row 0 column h frequency 0: position = crop top = 4, so sin = sin(4).
  EXPECT_NEAR(u.sin.as<float>()[16], std::sin(4.0), 2e-6);
  // Column w of token (0, 0, 1): linspace(0, 45*29/30, 30)[1] = 43.5/29 = 1.5.
  EXPECT_NEAR(u.sin.as<float>()[64 + 40], std::sin(1.5), 2e-6);
}

TEST(RopeTables, RejectsBadHeadDim) {
  EXPECT_THROW(ops::cogvideox_rope_tables(24, 1, 2, 2, 2, 2), Error);
}

// ---------------------------------------------------------------- RoPE application
void run_rope(vk::Context& ctx, int64_t B, int64_t L, int64_t first, int64_t n, int64_t H, int64_t Dh, int64_t stride,
              int64_t col, bool in_place) {
  std::vector<float> x = random_values(size_t(B * L * stride), 51 + uint32_t(Dh));
  std::vector<float> cs = random_values(size_t(n * Dh), 52, -1, 1), sn = random_values(size_t(n * Dh), 53, -1, 1);
  std::vector<float> want(x.size());
  for (size_t i = 0; i < x.size(); ++i) want[i] = in_place ? x[i] : 0.0f;
  for (int64_t b = 0; b < B; ++b)
    for (int64_t t = 0; t < n; ++t)
      for (int64_t h = 0; h < H; ++h)
        for (int64_t i = 0; i < Dh; i += 2) {
          size_t e = size_t((b * L + first + t) * stride + col + h * Dh + i), te = size_t(t * Dh + i);
          double x0 = x[e], x1 = x[e + 1];
          want[e] = float(x0 * cs[te] - x1 * sn[te]);
          want[e + 1] = float(x1 * cs[te + 1] + x0 * sn[te + 1]);
        }
  Tensor xt = Tensor::upload(ctx, HostTensor::from_f32({B * L, stride}, x));
  Tensor yt = in_place ? xt : Tensor::zeros(ctx, {B * L, stride}, DType::f32);
  Tensor ct = Tensor::upload(ctx, HostTensor::from_f32({n, Dh}, cs));
  Tensor st = Tensor::upload(ctx, HostTensor::from_f32({n, Dh}, sn));
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::rope(rec, xt, yt, B, L, first, H, Dh, col, ct, st); });
  EXPECT_LE(max_abs_diff(yt.download(ctx).to_f32(), want), 1e-6)
      << "rope B=" << B << " L=" << L << " first=" << first << " n=" << n << " H=" << H << " Dh=" << Dh;
}

// Tolerance: 1e-6 absolute (|x| <= 2, |cos|,|sin| <= 1: two products and a sum in fp32).
TEST_F(PositionOps, RopeOnVideoTokensOfFusedQkv) {
  // Tiny model: 8 text + 48 video tokens, 2 heads x 16, fused QKV [rows, 96]; q and k rotated in one call
  // as 4 heads from column 0.
  run_rope(ctx(), 2, 56, 8, 48, 4, 16, 96, 0, true);
  // Odd everything, out of place, k slice only.
  run_rope(ctx(), 3, 13, 5, 7, 3, 6, 3 * 3 * 6 + 1, 19, false);
  run_rope(ctx(), 1, 33, 0, 33, 1, 64, 64, 0, true);
}

TEST_F(PositionOps, RopeRejectsSliceOutsideSequence) {
  Tensor x = Tensor::zeros(ctx(), {2 * 10, 32}, DType::f32);
  Tensor c = Tensor::zeros(ctx(), {6, 16}, DType::f32);
  vk::Recorder rec(ctx());
  rec.begin();
  EXPECT_THROW(ops::rope(rec, x, x, 2, 10, 5, 2, 16, 0, c, c), Error);  // tokens [5, 11) > 10
  EXPECT_THROW(ops::rope(rec, x, x, 2, 10, 0, 2, 16, 8, c, c), Error);  // columns 8..40 > 32
}

// ---------------------------------------------------------------- timestep embedding
// Reference as diffusers computes it in fp32: exponent = (-ln(1e4) * k) / (half - shift), freq = exp()
// (correctly rounded here), arg = t * freq, then sin/cos of that fp32 argument (in double here). Also returns
// the per-element tolerance: 2e-6 plus one ulp of the argument (2^-23 * |arg|), because an fp32 exp that is
// off by one ulp (the shader's in ~1% of cases, torch's SLEEF exp too) moves t*freq by up to ~1 ulp.
void timestep_reference(const std::vector<float>& ts, int64_t D, bool flip, float shift, std::vector<float>& out,
                        std::vector<double>& tol) {
  const int64_t half = D / 2;
  out.assign(size_t(int64_t(ts.size()) * D), 0.0f);
  tol.assign(out.size(), 2e-6);
  const float neg_ln = float(-std::log(10000.0));
  for (size_t b = 0; b < ts.size(); ++b)
    for (int64_t k = 0; k < half; ++k) {
      volatile float e = neg_ln * float(k);
      float expo = e / (float(half) - shift);
      float freq = float(std::exp(double(expo)));
      float arg = ts[b] * freq;
      float s = float(std::sin(double(arg))), c = float(std::cos(double(arg)));
      size_t i0 = b * size_t(D) + size_t(k), i1 = b * size_t(D) + size_t(half + k);
      out[i0] = flip ? c : s;
      out[i1] = flip ? s : c;
      tol[i0] = tol[i1] = 2e-6 + std::ldexp(std::abs(double(arg)), -23);
    }
}

void run_timestep(vk::Context& ctx, const std::vector<float>& ts, int64_t D, bool flip, float shift) {
  const int64_t B = int64_t(ts.size());
  Tensor tt = Tensor::upload(ctx, HostTensor::from_f32({B}, ts));
  Tensor et = Tensor::empty(ctx, {B, D}, DType::f32);
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::timestep_embedding(rec, tt, et, flip, shift); });
  std::vector<float> got = et.download(ctx).to_f32(), want;
  std::vector<double> tol;
  timestep_reference(ts, D, flip, shift, want, tol);
  ASSERT_EQ(got.size(), want.size());
  size_t bad = 0, first_bad = 0, exact = 0;
  for (size_t i = 0; i < got.size(); ++i) {
    if (!(std::abs(double(got[i]) - double(want[i])) <= tol[i]) && bad++ == 0) first_bad = i;
    if (std::abs(double(got[i]) - double(want[i])) <= 2e-6) ++exact;
  }
  EXPECT_EQ(bad, 0u) << "timestep_embedding D=" << D << " flip=" << flip << ": element " << first_bad << " is "
                     << got[first_bad] << ", expected " << want[first_bad];
  // The one-ulp allowance is the exception: at least 95% of the values agree to 2e-6.
  EXPECT_GE(double(exact), 0.95 * double(got.size())) << "timestep_embedding D=" << D;
  if (D % 2 == 1) EXPECT_EQ(got[size_t(D - 1)], 0.0f);
}

// Tolerance: 2e-6 + 2^-23*|t*freq| per element (see timestep_reference); >= 95% within 2e-6.
TEST_F(PositionOps, TimestepEmbedding) {
  run_timestep(ctx(), {0.0f, 1.0f, 0.25f}, 32, true, 0.0f);
  run_timestep(ctx(), {999.0f, 500.0f, 981.0f, 1.0f, 0.0f, 37.5f, 750.0f}, 32, true, 0.0f);  // tiny model
  run_timestep(ctx(), {999.0f, 123.0f}, 3072, true, 0.0f);                                   // 48 heads x 64
  run_timestep(ctx(), {999.0f, 3.0f, 77.0f}, 33, false, 1.0f);  // odd D, [sin | cos], shift 1
}

}  // namespace
}  // namespace dvs
