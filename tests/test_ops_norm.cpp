// Norm ops (layernorm with adaLN modulation, per-head q/k layernorm, RMSNorm, GroupNorm) against plain C++
// references in double on random data, with odd sizes, large mean offsets (two-pass statistics), 16-bit
// weights and in-place use.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "support/gpu.hpp"
#include "support/stored_values.hpp"
#include "support/scoped_limits.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_norm.hpp"

namespace dvs {
namespace {

using test::GpuTest;
using NormOps = GpuTest;  // the suite name selects these for the DVS_TUNING=gpu pass

std::vector<float> random_values(size_t n, uint32_t seed, float offset = 0.0f, float spread = 1.0f) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> dist(0.0f, 1.0f);
  std::vector<float> v(n);
  for (float& x : v) x = offset + spread * dist(rng);
  return v;
}

using test::stored_as;

Tensor upload_f32(vk::Context& ctx, const std::vector<float>& v, Shape shape) {
  return Tensor::upload(ctx, HostTensor::from_f32(std::move(shape), v));
}

// |got - want| <= atol + rtol*|want| everywhere; reports the worst element.
void expect_close(const std::vector<float>& got, const std::vector<double>& want, double atol, double rtol,
                  const std::string& what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  double worst = -1e300;
  size_t at = 0;
  bool finite = true;
  for (size_t i = 0; i < got.size(); ++i) {
    double excess = std::abs(double(got[i]) - want[i]) - (atol + rtol * std::abs(want[i]));
    if (!std::isfinite(excess)) { finite = false; at = i; break; }
    if (excess > worst) { worst = excess; at = i; }
  }
  EXPECT_TRUE(finite && worst <= 0.0) << what << ": element " << at << " is " << got[at] << ", expected " << want[at];
}

void run_rmsnorm(vk::Context& ctx, int64_t rows, int64_t D, DType wdt, bool in_place);

// ---------------------------------------------------------------- LayerNorm
struct LnCase {
  int64_t B, L, D;
  DType wdt;
  bool affine, modulate, in_place;
  float offset;
};

std::vector<double> layernorm_ref(const std::vector<float>& x, int64_t rows, int64_t D, const std::vector<float>* w,
                                  const std::vector<float>* b, double eps) {
  std::vector<double> y(x.size());
  for (int64_t r = 0; r < rows; ++r) {
    double m = 0, v = 0;
    for (int64_t i = 0; i < D; ++i) m += x[size_t(r * D + i)];
    m /= double(D);
    for (int64_t i = 0; i < D; ++i) v += (x[size_t(r * D + i)] - m) * (x[size_t(r * D + i)] - m);
    v /= double(D);
    for (int64_t i = 0; i < D; ++i) {
      double t = (x[size_t(r * D + i)] - m) / std::sqrt(v + eps);
      if (w) t = t * (*w)[size_t(i)] + (*b)[size_t(i)];
      y[size_t(r * D + i)] = t;
    }
  }
  return y;
}

// A row wider than one binding is refused by design (model rows are at most 16 KiB, bindings at least
// 128 MiB): under a forced tiny DVS_LIMITS profile such cases are left out.
bool row_fits_binding(vk::Context& ctx, int64_t D) {
  return uint64_t(D) * 4 + 256 <= ctx.caps().max_storage_buffer_range;
}

void run_layernorm(vk::Context& ctx, const LnCase& c) {
  const int64_t rows = c.B * c.L, D = c.D;
  if (!row_fits_binding(ctx, D)) return;
  const float eps = 1e-5f;
  std::vector<float> x = random_values(size_t(rows * D), 11 + uint32_t(D), c.offset);
  std::vector<float> w = random_values(size_t(D), 12, 1.0f, 0.3f), b = random_values(size_t(D), 13, 0.0f, 0.5f);
  HostTensor wh = stored_as(w, {D}, c.wdt), bh = stored_as(b, {D}, c.wdt);
  std::vector<double> want = layernorm_ref(x, rows, D, c.affine ? &w : nullptr, c.affine ? &b : nullptr, eps);

  // Table [B, 6D] like CogVideoXLayerNormZero's chunks (shift, scale, gate, enc_shift, enc_scale, enc_gate).
  const int64_t W = 6 * D, split = c.L / 3;
  std::vector<float> table = random_values(size_t(c.B * W), 14, 0.0f, 0.5f);
  ops::Modulation mod;
  if (c.modulate) {
    mod.seq_len = c.L;
    mod.split = split;
    mod.shift_col[0] = 3 * D;  // text: enc_shift, enc_scale
    mod.scale_col[0] = 4 * D;
    mod.shift_col[1] = 0;  // video: shift, scale
    mod.scale_col[1] = D;
    for (int64_t r = 0; r < rows; ++r) {
      int64_t bt = r / c.L, set = (r % c.L) < split ? 0 : 1;
      for (int64_t i = 0; i < D; ++i) {
        double sc = table[size_t(bt * W + mod.scale_col[set] + i)], sh = table[size_t(bt * W + mod.shift_col[set] + i)];
        double& v = want[size_t(r * D + i)];
        v = v * (1.0 + sc) + sh;
      }
    }
  }

  Tensor xt = upload_f32(ctx, x, {c.B, c.L, D});
  Tensor yt = c.in_place ? xt : Tensor::empty(ctx, {c.B, c.L, D}, DType::f32);
  Tensor wt, bt;
  if (c.affine) {
    wt = Tensor::upload(ctx, wh);
    bt = Tensor::upload(ctx, bh);
  }
  if (c.modulate) mod.table = upload_f32(ctx, table, {c.B, W});
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::layernorm(rec, xt, yt, wt, bt, eps, c.modulate ? &mod : nullptr); });
  // Inputs with offset o carry rounding ulp(o)/2 that the normalisation scales by 1/std (std = 1 here).
  const double atol = 2e-5 + 2e-7 * std::abs(c.offset);
  expect_close(yt.download(ctx).to_f32(), want, atol, 1e-5,
               "layernorm B=" + std::to_string(c.B) + " L=" + std::to_string(c.L) + " D=" + std::to_string(D) + " " +
                   dtype_name(c.wdt) + (c.affine ? " affine" : "") + (c.modulate ? " modulated" : "") +
                   (c.in_place ? " in-place" : ""));
}

// Tolerance: |err| <= 2e-5 + 2e-7*|offset| + 1e-5*|ref|.
TEST_F(NormOps, LayerNormOddShapes) {
  for (int64_t D : {1, 7, 33, 129, 1000})
    run_layernorm(ctx(), {1, 5, D, DType::f32, true, false, false, 0.0f});
  run_layernorm(ctx(), {3, 7, 64, DType::f32, false, false, false, 0.0f});
  run_layernorm(ctx(), {1, 1, 3072, DType::f32, true, false, false, 0.0f});
  run_layernorm(ctx(), {1, 2, 4100, DType::f32, true, false, false, 0.0f});  // beyond the register cache
}

TEST_F(NormOps, LayerNormLargeOffsetIsTwoPass) {
  run_layernorm(ctx(), {2, 9, 257, DType::f32, false, false, false, 1000.0f});
}

TEST_F(NormOps, LayerNormHalfWeightsAndInPlace) {
  run_layernorm(ctx(), {1, 4, 33, DType::bf16, true, false, false, 0.5f});
  run_layernorm(ctx(), {1, 4, 33, DType::f16, true, false, true, 0.5f});
  run_layernorm(ctx(), {1, 3, 72, DType::bf16, true, false, true, 0.5f});  // vec4 path, 16-bit weights
  run_layernorm(ctx(), {1, 3, 72, DType::f16, true, false, false, 0.5f});
}

TEST_F(NormOps, LayerNormZeroModulationTextVideoSplit) {
  // Tiny model: 8 text + 32 video tokens, D = 32; split at L/3 of 40 = 13 here to exercise an odd split.
  run_layernorm(ctx(), {2, 40, 32, DType::f32, true, true, false, 0.0f});
  run_layernorm(ctx(), {3, 7, 33, DType::bf16, true, true, true, 0.0f});
  run_layernorm(ctx(), {2, 5, 16, DType::f32, false, true, false, 0.0f});  // AdaLayerNorm-like, no affine
}

// Both row mappings (the default one is the device's tuning): the same checks on a subset.
TEST_F(NormOps, LayerNormAndRmsNormBothMappings) {
  for (const char* m : {"norm_row_per_invocation=off", "norm_row_per_invocation=on"}) {
    SCOPED_TRACE(m);
    ops::ScopedTuningOverride mapping(m);
    run_layernorm(ctx(), {1, 5, 33, DType::f32, true, false, false, 0.0f});
    run_layernorm(ctx(), {1, 2, 4100, DType::f32, true, false, false, 0.0f});
    run_layernorm(ctx(), {2, 9, 257, DType::f32, false, false, false, 1000.0f});
    run_layernorm(ctx(), {2, 40, 32, DType::bf16, true, true, false, 0.0f});
    run_layernorm(ctx(), {3, 7, 33, DType::f16, true, true, true, 0.0f});
    run_rmsnorm(ctx(), 3, 33, DType::f32, false);
    run_rmsnorm(ctx(), 2, 4100, DType::bf16, true);
  }
}

// An f16 y (the activation of a GEMM on tensor cores): each value the f32 y's rounded to nearest even, bit for
// bit (the same statistics, one rounding), with affine and modulation, both row mappings, a row past the register
// cache, and y a view 64 rows into a larger f16 tensor; an f16 y off the 4-element path is refused.
TEST_F(NormOps, LayerNormHalfOutput) {
  vk::Context& c = ctx();
  auto run = [&](const LnCase& k) {
    const int64_t rows = k.B * k.L, D = k.D;
    std::vector<float> x = random_values(size_t(rows * D), 21 + uint32_t(D), k.offset);
    std::vector<float> w = random_values(size_t(D), 22, 1.0f, 0.3f), b = random_values(size_t(D), 23, 0.0f, 0.5f);
    std::vector<float> table = random_values(size_t(k.B * 6 * D), 24, 0.0f, 0.5f);
    Tensor xt = upload_f32(c, x, {k.B, k.L, D});
    Tensor wt, bt;
    if (k.affine) {
      wt = Tensor::upload(c, stored_as(w, {D}, k.wdt));
      bt = Tensor::upload(c, stored_as(b, {D}, k.wdt));
    }
    ops::Modulation mod;
    if (k.modulate) {
      mod.table = upload_f32(c, table, {k.B, 6 * D});
      mod.seq_len = k.L;
      mod.split = k.L / 3;
      mod.shift_col[0] = 3 * D, mod.scale_col[0] = 4 * D, mod.shift_col[1] = 0, mod.scale_col[1] = D;
    }
    Tensor y32 = Tensor::empty(c, {k.B, k.L, D}, DType::f32);
    Tensor big = Tensor::zeros(c, {64 + rows + 5, D}, DType::f16);  // y: rows 64.. of it (256-byte aligned)
    Tensor y16 = big.rows(64, rows).reshape({k.B, k.L, D});
    ops::run_now(c, [&](vk::Recorder& rec) {
      ops::layernorm(rec, xt, y32, wt, bt, 1e-5f, k.modulate ? &mod : nullptr);
      ops::layernorm(rec, xt, y16, wt, bt, 1e-5f, k.modulate ? &mod : nullptr);
    });
    const std::vector<float> f = y32.download(c).to_f32();
    const HostTensor h = big.download(c);
    size_t differ = 0;
    for (size_t i = 0; i < f.size(); ++i) differ += h.as<uint16_t>()[size_t(64 * D) + i] != f32_to_f16(f[i]);
    EXPECT_EQ(differ, 0u) << "D=" << D << ": f16 values that are not the f32 y rounded";
    for (int64_t i = 0; i < 64 * D; ++i) ASSERT_EQ(h.as<uint16_t>()[size_t(i)], 0u) << "written before the view";
    for (int64_t i = (64 + rows) * D; i < (69 + rows) * D; ++i) ASSERT_EQ(h.as<uint16_t>()[size_t(i)], 0u) << "after";
  };
  for (const char* m : {"norm_row_per_invocation=off", "norm_row_per_invocation=on"}) {
    SCOPED_TRACE(m);
    ops::ScopedTuningOverride mapping(m);
    run({2, 40, 32, DType::bf16, true, true, false, 0.0f});
    run({1, 2, 4100, DType::f32, true, false, false, 0.0f});
    run({3, 5, 72, DType::f16, false, false, false, 3.0f});
  }
  Tensor x = Tensor::zeros(c, {2, 5, 33}, DType::f32), y = Tensor::zeros(c, {2, 5, 33}, DType::f16), none;
  EXPECT_THROW(ops::run_now(c, [&](vk::Recorder& rec) { ops::layernorm(rec, x, y, none, none, 1e-5f); }), Error);
}

TEST_F(NormOps, LayerNormRejectsBadModulation) {
  Tensor x = Tensor::zeros(ctx(), {2, 4, 8}, DType::f32), w, b;
  ops::Modulation mod;
  mod.table = Tensor::zeros(ctx(), {2, 16}, DType::f32);
  mod.seq_len = 4;
  mod.scale_col[1] = 12;  // 12 + 8 > 16
  vk::Recorder rec(ctx());
  rec.begin();
  EXPECT_THROW(ops::layernorm(rec, x, x, w, b, 1e-5f, &mod), Error);
  mod.scale_col[1] = 8;
  mod.seq_len = 3;  // 8 rows are not [2, 3]
  EXPECT_THROW(ops::layernorm(rec, x, x, w, b, 1e-5f, &mod), Error);
}

// ---------------------------------------------------------------- per-head LayerNorm
void run_head_layernorm(vk::Context& ctx, int64_t rows, int64_t H, int64_t Dh, int64_t stride, int64_t col, DType wdt,
                        bool affine, bool in_place) {
  std::vector<float> x = random_values(size_t(rows * stride), 21 + uint32_t(Dh), 3.0f, 2.0f);
  std::vector<float> w = random_values(size_t(Dh), 22, 1.0f, 0.3f), b = random_values(size_t(Dh), 23, 0.0f, 0.3f);
  HostTensor wh = stored_as(w, {Dh}, wdt), bh = stored_as(b, {Dh}, wdt);
  const double eps = 1e-6;
  // Outside the slice: in place keeps x, out of place leaves y's initial content (zeros).
  std::vector<double> want(x.size());
  for (size_t i = 0; i < x.size(); ++i) want[i] = in_place ? x[i] : 0.0;
  for (int64_t r = 0; r < rows; ++r)
    for (int64_t h = 0; h < H; ++h) {
      const float* s = &x[size_t(r * stride + col + h * Dh)];
      double m = 0, v = 0;
      for (int64_t i = 0; i < Dh; ++i) m += s[i];
      m /= double(Dh);
      for (int64_t i = 0; i < Dh; ++i) v += (s[i] - m) * (s[i] - m);
      v /= double(Dh);
      for (int64_t i = 0; i < Dh; ++i) {
        double t = (s[i] - m) / std::sqrt(v + eps);
        if (affine) t = t * w[size_t(i)] + b[size_t(i)];
        want[size_t(r * stride + col + h * Dh + i)] = t;
      }
    }
  Tensor xt = upload_f32(ctx, x, {rows, stride});
  Tensor yt = in_place ? xt : Tensor::zeros(ctx, {rows, stride}, DType::f32);
  Tensor wt, bt;
  if (affine) {
    wt = Tensor::upload(ctx, wh);
    bt = Tensor::upload(ctx, bh);
  }
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::head_layernorm(rec, xt, yt, H, Dh, col, wt, bt, 1e-6f); });
  expect_close(yt.download(ctx).to_f32(), want, 1e-5, 1e-5,
               "head_layernorm rows=" + std::to_string(rows) + " H=" + std::to_string(H) + " Dh=" + std::to_string(Dh));
}

// Tolerance: 1e-5 + 1e-5*|ref|.
TEST_F(NormOps, HeadLayerNormOnFusedQkvSlices) {
  // Tiny model: 2 heads x 16, fused QKV [rows, 96]: q at column 0, k at column 32.
  run_head_layernorm(ctx(), 70, 1, 16, 16, 0, DType::f32, false, false);  // several workgroups
  run_head_layernorm(ctx(), 40, 2, 16, 96, 0, DType::f32, true, true);
  run_head_layernorm(ctx(), 40, 2, 16, 96, 32, DType::bf16, true, true);
  // Odd everything, out of place, no affine, f16.
  run_head_layernorm(ctx(), 7, 3, 7, 3 * 3 * 7 + 5, 21 + 2, DType::f32, false, false);
  run_head_layernorm(ctx(), 5, 2, 6, 2 * 6 * 3, 12, DType::bf16, true, true);  // scalar path with affine
  run_head_layernorm(ctx(), 33, 5, 64, 5 * 64 * 3, 5 * 64, DType::f16, true, false);
}

// ---------------------------------------------------------------- RMSNorm
void run_rmsnorm(vk::Context& ctx, int64_t rows, int64_t D, DType wdt, bool in_place) {
  if (!row_fits_binding(ctx, D)) return;
  std::vector<float> x = random_values(size_t(rows * D), 31 + uint32_t(D), 0.7f, 3.0f);
  std::vector<float> w = random_values(size_t(D), 32, 1.0f, 0.3f);
  HostTensor wh = stored_as(w, {D}, wdt);
  std::vector<double> want(x.size());
  for (int64_t r = 0; r < rows; ++r) {
    double s = 0;
    for (int64_t i = 0; i < D; ++i) s += double(x[size_t(r * D + i)]) * x[size_t(r * D + i)];
    double rs = 1.0 / std::sqrt(s / double(D) + 1e-6);
    for (int64_t i = 0; i < D; ++i) want[size_t(r * D + i)] = w[size_t(i)] * (x[size_t(r * D + i)] * rs);
  }
  Tensor xt = upload_f32(ctx, x, {rows, D});
  Tensor yt = in_place ? xt : Tensor::empty(ctx, {rows, D}, DType::f32);
  Tensor wt = Tensor::upload(ctx, wh);
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::rmsnorm(rec, xt, yt, wt, 1e-6f); });
  expect_close(yt.download(ctx).to_f32(), want, 1e-6, 1e-5,
               "rmsnorm rows=" + std::to_string(rows) + " D=" + std::to_string(D) + " " + dtype_name(wdt));
}

// Tolerance: 1e-6 + 1e-5*|ref|.
TEST_F(NormOps, RmsNorm) {
  for (int64_t D : {1, 7, 33, 129}) run_rmsnorm(ctx(), 3, D, DType::f32, false);
  run_rmsnorm(ctx(), 8, 32, DType::bf16, true);  // tiny T5: d_model 32
  run_rmsnorm(ctx(), 2, 4096, DType::f16, false);
  run_rmsnorm(ctx(), 2, 4100, DType::f32, false);  // beyond the register cache
}

// ---------------------------------------------------------------- GroupNorm
void run_groupnorm(vk::Context& ctx, Shape shape, int64_t G, DType wdt, bool affine, bool silu, float offset,
                   bool in_place) {
  const int64_t B = shape[0], C = shape[1], S = shape_numel(shape) / (B * C);
  const double eps = 1e-6;
  std::vector<float> x = random_values(size_t(shape_numel(shape)), 41 + uint32_t(C), offset, 1.5f);
  std::vector<float> w = random_values(size_t(C), 42, 1.0f, 0.3f), b = random_values(size_t(C), 43, 0.0f, 0.3f);
  HostTensor wh = stored_as(w, {C}, wdt), bh = stored_as(b, {C}, wdt);
  std::vector<double> want(x.size());
  const int64_t cg = C / G, len = cg * S;
  for (int64_t bi = 0; bi < B; ++bi)
    for (int64_t g = 0; g < G; ++g) {
      const float* s = &x[size_t((bi * C + g * cg) * S)];
      double m = 0, v = 0;
      for (int64_t i = 0; i < len; ++i) m += s[i];
      m /= double(len);
      for (int64_t i = 0; i < len; ++i) v += (s[i] - m) * (s[i] - m);
      v /= double(len);
      for (int64_t i = 0; i < len; ++i) {
        int64_t c = g * cg + i / S;
        double t = (s[i] - m) / std::sqrt(v + eps);
        if (affine) t = t * w[size_t(c)] + b[size_t(c)];
        if (silu) t = t / (1.0 + std::exp(-t));
        want[size_t((bi * C + g * cg) * S + i)] = t;
      }
    }
  Tensor xt = upload_f32(ctx, x, shape);
  Tensor yt = in_place ? xt : Tensor::empty(ctx, shape, DType::f32);
  Tensor wt, bt;
  if (affine) {
    wt = Tensor::upload(ctx, wh);
    bt = Tensor::upload(ctx, bh);
  }
  Tensor scratch = Tensor::empty(ctx, {ops::groupnorm_scratch_elems(shape, G)}, DType::f32);
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::groupnorm(rec, xt, yt, G, wt, bt, float(eps), silu, scratch); });
  expect_close(yt.download(ctx).to_f32(), want, 2e-5 + 2e-7 * std::abs(offset), 2e-5,
               "groupnorm [" + shape_str(shape) + "] G=" + std::to_string(G) + " " + dtype_name(wdt));
}

// Tolerance: 2e-5 + 2e-7*|offset| + 2e-5*|ref|.
TEST_F(NormOps, GroupNormOddShapes) {
  run_groupnorm(ctx(), {2, 8, 3, 5, 7}, 4, DType::f32, true, false, 0.0f, false);
  run_groupnorm(ctx(), {1, 3, 1, 1, 1}, 3, DType::f32, true, true, 0.0f, false);  // one element per group
  run_groupnorm(ctx(), {1, 6, 2, 9, 11}, 2, DType::bf16, true, true, 0.0f, true);
  run_groupnorm(ctx(), {2, 4, 33, 7}, 1, DType::f16, false, true, 0.0f, false);  // 4-D input, no affine
  run_groupnorm(ctx(), {2, 6, 2, 4, 6}, 3, DType::bf16, true, false, 1.0f, false);  // vec4 path (S = 48)
}

TEST_F(NormOps, GroupNormLargeGroupWithOffset) {
  // Tiny-VAE-like: 32 channels / 8 groups, 9 frames of 60x90: 194,400 elements per group (48 blocks), mean 50.
  if (test::over_allocation_limit(ctx(), 32ull * 9 * 60 * 90 * 4, "GroupNorm 1x32x9x60x90")) GTEST_SKIP();
  run_groupnorm(ctx(), {1, 32, 9, 60, 90}, 8, DType::f32, true, true, 50.0f, false);
}

}  // namespace
}  // namespace dvs
