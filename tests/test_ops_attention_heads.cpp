// ops::attention_heads (q, k or v for the flash attention kernels: per-head LayerNorm, RoPE, fp16, head-major) against
// a double-precision reference on the host, at odd sizes (heads, head_dim 4·odd, tokens, the rotated token range,
// affine weights f32/bf16/f16 or none, a mean offset that a one-pass variance would lose); the f16 output must be
// the f32 output's bits rounded to nearest even, nothing written outside y. Its row chunks under forced limits give
// the whole call's bytes. Then the attention with those operands: f16 head-major q, k, v give every flash kernel's
// bits of f32 token-major ones (raw values where the kernel rounds them to fp16 itself: the same rounding), head-major
// f32 the tiled kernel's, and the calls that must refuse head-major operands.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "support/attention_reference.hpp"
#include "support/expect_error.hpp"
#include "support/gpu.hpp"
#include "support/kernel_calls.hpp"
#include "support/scoped_limits.hpp"
#include "support/split_check.hpp"
#include "support/stored_values.hpp"
#include "tensor/coopmat_layout.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_attention.hpp"
#include "tensor/ops_norm.hpp"

namespace dvs::test {
namespace {

std::vector<float> normal(size_t n, uint32_t seed, float mean = 0.0f, float sd = 1.0f) {
  std::mt19937 gen(seed);
  std::normal_distribution<float> dist(mean, sd);
  std::vector<float> v(n);
  for (float& x : v) x = dist(gen);
  return v;
}

// One op case: x [B, L, H·D]; the affine (weight_dtype; none when `affine` is false) under `norm`; RoPE tables of
// `n_rot` random rows from token `rope_first` (0 rows: no RoPE).
struct Case {
  int64_t B, L, H, D;
  bool norm, affine;
  DType weight_dtype;
  int64_t rope_first, n_rot;
  float x_mean;
  float x_sd = 1.0f;
};

std::string describe(const Case& c) {
  return "B" + std::to_string(c.B) + " L" + std::to_string(c.L) + " H" + std::to_string(c.H) + " D" +
         std::to_string(c.D) + (c.norm ? (c.affine ? " norm+affine " + std::string(dtype_name(c.weight_dtype)) : " norm")
                                        : " no norm") +
         " rope [" + std::to_string(c.rope_first) + ", " + std::to_string(c.rope_first + c.n_rot) + ")";
}

// The reference: y[b][h][l][d] in double from the host copies.
std::vector<double> reference(const Case& c, const std::vector<float>& x, const std::vector<float>& w,
                              const std::vector<float>& bias, const std::vector<float>& cs,
                              const std::vector<float>& sn) {
  const int64_t W = c.H * c.D;
  std::vector<double> y(size_t(c.B * c.H * c.L * c.D));
  std::vector<double> v(size_t(c.D));
  for (int64_t b = 0; b < c.B; ++b)
    for (int64_t l = 0; l < c.L; ++l)
      for (int64_t h = 0; h < c.H; ++h) {
        const float* src = &x[size_t((b * c.L + l) * W + h * c.D)];
        for (int64_t d = 0; d < c.D; ++d) v[size_t(d)] = src[d];
        if (c.norm) {
          double mean = 0, var = 0;
          for (double e : v) mean += e;
          mean /= double(c.D);
          for (double e : v) var += (e - mean) * (e - mean);
          const double rstd = 1.0 / std::sqrt(var / double(c.D) + 1e-6);
          for (int64_t d = 0; d < c.D; ++d) {
            v[size_t(d)] = (v[size_t(d)] - mean) * rstd;
            if (c.affine) v[size_t(d)] = v[size_t(d)] * w[size_t(d)] + bias[size_t(d)];
          }
        }
        if (l >= c.rope_first && l < c.rope_first + c.n_rot) {
          const size_t t = size_t((l - c.rope_first) * c.D);
          std::vector<double> r = v;
          for (int64_t i = 0; i < c.D; i += 2) {
            r[size_t(i)] = v[size_t(i)] * cs[t + size_t(i)] - v[size_t(i + 1)] * sn[t + size_t(i)];
            r[size_t(i + 1)] = v[size_t(i + 1)] * cs[t + size_t(i + 1)] + v[size_t(i)] * sn[t + size_t(i + 1)];
          }
          v = r;
        }
        for (int64_t d = 0; d < c.D; ++d) y[size_t(((b * c.H + h) * c.L + l) * c.D + d)] = v[size_t(d)];
      }
  return y;
}

constexpr int64_t kGuard = 16;  // elements of y's buffer before and after it, never written

class AttentionHeadsOps : public GpuTest {
 protected:
  struct Inputs {
    std::vector<float> x, w, b, cs, sn;
    Tensor tx, tw, tb, tcos, tsin;
    ops::AttentionHeadsOptions opt;
  };
  Inputs inputs(const Case& c, uint32_t seed) {
    Inputs in;
    in.x = normal(size_t(c.B * c.L * c.H * c.D), seed, c.x_mean, c.x_sd);
    in.tx = Tensor::upload(ctx(), HostTensor::from_f32({c.B, c.L, c.H * c.D}, in.x));
    in.opt.norm = c.norm;
    in.opt.eps = 1e-6f;
    if (c.norm && c.affine) {
      in.w = normal(size_t(c.D), seed + 1, 1.0f, 0.5f);
      in.b = normal(size_t(c.D), seed + 2, 0.0f, 0.5f);
      in.opt.norm_weight = Tensor::upload(ctx(), stored_as(in.w, {c.D}, c.weight_dtype));
      in.opt.norm_bias = Tensor::upload(ctx(), stored_as(in.b, {c.D}, c.weight_dtype));
    }
    if (c.n_rot > 0) {  // independent random tables: swapped cos/sin or a shifted row show
      in.cs = normal(size_t(c.n_rot * c.D), seed + 3);
      in.sn = normal(size_t(c.n_rot * c.D), seed + 4);
      in.opt.rope = true;
      in.opt.cos = Tensor::upload(ctx(), HostTensor::from_f32({c.n_rot, c.D}, in.cs));
      in.opt.sin = Tensor::upload(ctx(), HostTensor::from_f32({c.n_rot, c.D}, in.sn));
      in.opt.rope_first = c.rope_first;
    }
    return in;
  }
  // y of `dt` inside a buffer with kGuard elements of `fill` bits before and after it.
  Tensor guarded(const Case& c, DType dt, Tensor& whole) {
    const int64_t n = c.B * c.H * c.L * c.D;
    HostTensor h({n + 2 * kGuard}, dt);
    std::memset(h.data.data(), 0x5a, h.data.size());
    whole = Tensor::upload(ctx(), h);
    const VkDeviceSize es = dtype_size(dt);
    return Tensor::on(whole.buffer().sub(VkDeviceSize(kGuard) * es, VkDeviceSize(n) * es), {c.B, c.H, c.L, c.D}, dt);
  }
  void check(const Case& c, uint32_t seed) {
    SCOPED_TRACE(describe(c));
    Inputs in = inputs(c, seed);
    Tensor whole32, whole16;
    const Tensor y32 = guarded(c, DType::f32, whole32), y16 = guarded(c, DType::f16, whole16);
    ops::run_now(ctx(), [&](vk::Recorder& rec) {
      ops::attention_heads(rec, in.tx, y32, c.H, in.opt);
      ops::attention_heads(rec, in.tx, y16, c.H, in.opt);
    });
    const std::vector<double> ref = reference(c, in.x, in.w, in.b, in.cs, in.sn);
    const HostTensor h32 = whole32.download(ctx()), h16 = whole16.download(ctx());
    const float* f = h32.as<float>() + kGuard;
    const uint16_t* bits = h16.as<uint16_t>() + kGuard;
    size_t far = 0, unrounded = 0, guard = 0;
    double worst = 0;
    for (size_t i = 0; i < ref.size(); ++i) {
      const double err = std::abs(double(f[i]) - ref[i]);
      worst = std::max(worst, err);
      far += err > 2e-5 * (1.0 + std::abs(ref[i])) || !std::isfinite(f[i]);
      unrounded += bits[i] != f32_to_f16(f[i]);
    }
    for (int64_t i = 0; i < kGuard; ++i) {
      guard += h32.as<uint32_t>()[i] != 0x5a5a5a5au || h32.as<uint32_t>()[h32.numel() - 1 - i] != 0x5a5a5a5au;
      guard += h16.as<uint16_t>()[i] != 0x5a5a || h16.as<uint16_t>()[h16.numel() - 1 - i] != 0x5a5a;
    }
    EXPECT_EQ(far, 0u) << "f32 elements off the double reference (worst |diff| " << worst << ")";
    EXPECT_EQ(unrounded, 0u) << "f16 elements that are not the f32 result rounded to nearest even";
    EXPECT_EQ(guard, 0u) << "elements written outside y";
  }
};

TEST_F(AttentionHeadsOps, MatchesADoubleReferenceAtOddSizes) {
  uint32_t seed = 3100;
  // k of a text-then-video sequence: norm (f32 affine, a large mean offset), RoPE on the tokens after the text.
  check({2, 11, 3, 12, true, true, DType::f32, 3, 8, 40.0f}, seed += 10);
  // q of a video chunk: every token rotated; bf16 and f16 affine; head_dim 20 and 64.
  check({1, 9, 5, 20, true, true, DType::bf16, 0, 9, 0.0f}, seed += 10);
  check({2, 7, 2, 64, true, true, DType::f16, 0, 7, 1.0f}, seed += 10);
  // Rotated tokens in the middle of the sequence; a norm without affine.
  check({3, 13, 1, 8, true, false, DType::f32, 5, 4, -3.0f}, seed += 10);
  // v: neither norm nor RoPE (the layout and the rounding only); head_dim 4 and 256.
  check({2, 5, 3, 4, false, false, DType::f32, 0, 0, 0.0f}, seed += 10);
  // v of tiny values: fp16 subnormals (below 2^-14), rounded to nearest even too.
  check({2, 5, 3, 8, false, false, DType::f32, 0, 0, 0.0f, 2e-5f}, seed += 10);
  check({1, 3, 2, 256, true, true, DType::f32, 1, 2, 0.0f}, seed += 10);
}

TEST_F(AttentionHeadsOps, RowChunksGiveTheWholeCallsBytes) {
  // x 2x37 tokens of 3x16 f32 = 14 KiB over 8 KiB bindings; y f16 = 7 KiB in one.
  const Case c{2, 37, 3, 16, true, true, DType::bf16, 9, 25, 2.0f};
  Inputs in = inputs(c, 3300);
  expect_split_equal(ctx(), "binding=8KiB", {c.B, c.H, c.L, c.D}, DType::f16,
                     [&](vk::Recorder& rec, const Tensor& y) { ops::attention_heads(rec, in.tx, y, c.H, in.opt); },
                     "attention_heads");
}

TEST_F(AttentionHeadsOps, RefusesWhatItCannotDo) {
  const Case c{1, 4, 2, 8, true, true, DType::f32, 1, 3, 0.0f};
  Inputs in = inputs(c, 3400);
  auto run = [&](const Tensor& x, const Tensor& y, int64_t heads, const ops::AttentionHeadsOptions& o) {
    ops::run_now(ctx(), [&](vk::Recorder& rec) { ops::attention_heads(rec, x, y, heads, o); });
  };
  const Tensor y = Tensor::zeros(ctx(), {1, 2, 4, 8}, DType::f16);
  // y token-major (the layout the op does not write); a head_dim that is not a multiple of 4.
  expect_error([&] { run(in.tx, Tensor::zeros(ctx(), {1, 4, 2, 8}, DType::f16), 2, in.opt); }, {"y is", "1x2x4x8"});
  const Tensor x6 = Tensor::zeros(ctx(), {1, 4, 12}, DType::f32);
  expect_error([&] { run(x6, Tensor::zeros(ctx(), {1, 2, 4, 6}, DType::f16), 2, {}); }, {"head_dim 6", "multiple of 4"});
  // Rotated tokens past the end; the tables' width; only a weight.
  ops::AttentionHeadsOptions late = in.opt;
  late.rope_first = 2;
  expect_error([&] { run(in.tx, y, 2, late); }, {"tokens [2, 5)", "4 tokens"});
  ops::AttentionHeadsOptions wide = in.opt;
  wide.cos = wide.sin = Tensor::zeros(ctx(), {3, 16}, DType::f32);
  expect_error([&] { run(in.tx, y, 2, wide); }, {"cos is"});
  ops::AttentionHeadsOptions half = in.opt;
  half.norm_bias = Tensor();
  expect_error([&] { run(in.tx, y, 2, half); }, {"weight and bias must both be given"});
  // y over one binding: a device error (the attention that reads y could not bind it either).
  ScopedLimits small(ctx(), "binding=4KiB");
  const Case big{1, 80, 2, 16, false, false, DType::f32, 0, 0, 0.0f};
  Inputs bin = inputs(big, 3410);
  const Tensor ybig = Tensor::zeros(ctx(), {1, 2, 80, 16}, DType::f32);
  expect_error([&] { run(bin.tx, ybig, 2, bin.opt); }, {"does not fit one binding", "maxStorageBufferRange"});
}

// ---- the attention with head-major operands ----

using ops::AttentionOperand;
using ops::AttentionShape;

class HeadMajorAttentionOps : public GpuTest {
 protected:
  // An operand as f32 token-major (its values rounded to fp16, or as they are: `raw`), and head-major `dt` holding
  // the values rounded to fp16 (to nearest even, on the host). `host` receives the token-major values.
  struct Pair {
    AttentionOperand token, heads;
  };
  Pair operand(const attention_ref::HostOperand& h, const AttentionShape& s, int64_t len, DType dt, bool raw,
               attention_ref::HostOperand* host = nullptr) {
    const int64_t D = s.head_dim, W = s.heads * D;
    std::vector<float> tok(size_t(s.batch * len * W));
    HostTensor hm({s.batch, s.heads, len, D}, dt);
    for (int64_t b = 0; b < s.batch; ++b)
      for (int64_t l = 0; l < len; ++l)
        for (int64_t hd = 0; hd < s.heads; ++hd)
          for (int64_t d = 0; d < D; ++d) {
            const float x = h.at(b * len + l, hd, d, D), v = f16_to_f32(f32_to_f16(x));
            tok[size_t((b * len + l) * W + hd * D + d)] = raw ? x : v;
            const size_t at = size_t(((b * s.heads + hd) * len + l) * D + d);
            if (dt == DType::f32) hm.as<float>()[at] = v;
            else hm.as<uint16_t>()[at] = f32_to_f16(v);
          }
    if (host) *host = {tok, 0, W};
    Pair p;
    p.token = {Tensor::upload(ctx(), HostTensor::from_f32({s.batch, len, W}, tok))};
    p.heads = {Tensor::upload(ctx(), hm), 0, 0, true};
    return p;
  }
  // The call with token-major f32 q, k, v and with head-major `dt` ones: the same bits, and near the double reference
  // (within the fp16 rounding of P on the tensor-core kernels). A kernel that rounds its operands to fp16 itself
  // (`rounds`: the tensor-core kernels and the twin) gets the raw f32 values token-major, so its rounding must be the
  // host's (to nearest even) too; the tiled kernel (fp32 arithmetic) gets the rounded values both ways.
  void same_bits(const AttentionShape& s, const std::string& shader, DType dt, bool rounds, uint32_t seed) {
    SCOPED_TRACE(shader + " D" + std::to_string(s.head_dim) + " head-major " + dtype_name(dt));
    const attention_ref::Operands in = attention_ref::random_operands(ctx(), s, false, 4, seed);
    attention_ref::HostOperand hq, hk, hv;
    const Pair q = operand(in.hq, s, s.q_len, dt, rounds, &hq), k = operand(in.hk, s, s.kv_len, dt, rounds, &hk),
               v = operand(in.hv, s, s.kv_len, dt, rounds, &hv);
    const int64_t W = s.heads * s.head_dim;
    const Tensor out_token = Tensor::zeros(ctx(), {s.batch, s.q_len, W}, DType::f32);
    const Tensor out_heads = Tensor::zeros(ctx(), {s.batch, s.q_len, W}, DType::f32);
    const ops::AttentionOptions opt{.scale = 1.0f / std::sqrt(float(s.head_dim))};
    if (!ops::attention_takes_f16(ctx().caps(), s, q.token, k.token, v.token, {out_token}, opt)) {
      ASSERT_TRUE(ctx().caps().forced_limits.any()) << "a flash kernel's call must take head-major operands";
      GTEST_SKIP() << "the limits in force send this call to the texel kernel";
    }
    const uint64_t before = kernel_calls(ctx(), shader);
    ops::run_now(ctx(), [&](vk::Recorder& rec) {
      ops::attention(rec, s, q.token, k.token, v.token, {out_token}, opt);
      ops::attention(rec, s, q.heads, k.heads, v.heads, {out_heads}, opt);
    });
    EXPECT_EQ(kernel_calls(ctx(), shader), before + 2) << "not run by " << shader;
    const HostTensor a = out_token.download(ctx()), b = out_heads.download(ctx());
    const std::vector<float> fa = a.to_f32();
    const std::vector<double> ref = attention_ref::reference(s, hq, hk, hv, opt.scale, nullptr, nullptr);
    size_t far = 0;
    for (size_t i = 0; i < ref.size(); ++i) far += !(std::abs(fa[i] - ref[i]) <= 5e-3 * (1.0 + std::abs(ref[i])));
    EXPECT_EQ(far, 0u) << "token-major elements off the double reference";
    EXPECT_EQ(std::memcmp(a.data.data(), b.data.data(), a.data.size()), 0)
        << "head-major q, k, v give another result than token-major ones holding the same values";
  }
};

TEST_F(HeadMajorAttentionOps, SameBitsAsTokenMajorOnEveryFlashKernel) {
  uint32_t seed = 3500;
  {
    ops::ScopedTuningOverride tiled("attention=tiled");
    for (int64_t d : {64, 12}) {
      same_bits({2, 3, d, 37, 45}, "nn/attention_flash", DType::f16, false, seed++);
      same_bits({2, 3, d, 37, 45}, "nn/attention_flash", DType::f32, false, seed++);
    }
  }
  if (ctx().caps().float16_arithmetic) {
    ops::ScopedTuningOverride twin(
        "attention=tiled,attention_coopmat_twin=on,attention_block_k=32,attention_coopmat_subgroups=4");
    same_bits({2, 3, 32, 37, 45}, "nn/attention_flash_coopmat_twin", DType::f16, true, seed++);
  }
  if (!ops::device_tuning(ctx().caps()).coopmat.defined()) {
    std::cout << "[ SKIPPED  ] the tensor-core kernels: no cooperative-matrix shape on this device\n";
    return;
  }
  {
    ops::ScopedTuningOverride khr("attention=coopmat,attention_coopmat2=off");
    same_bits({2, 3, 32, 37, 45}, "nn/attention_flash_coopmat", DType::f16, true, seed++);
  }
  const ops::CoopmatAttention a = ops::attention_coopmat_layout(ops::device_tuning(ctx().caps()));
  if (ctx().caps().cooperative_matrix2_row_ops && a.frag.n == a.frag.k) {
    ops::ScopedTuningOverride nv("attention=coopmat,attention_coopmat2=on");
    same_bits({2, 3, 32, 37, 45}, "nn/attention_flash_coopmat2", DType::f16, true, seed++);
  }
}

TEST_F(HeadMajorAttentionOps, RefusedWhereNoFlashKernelTakesThem) {
  const AttentionShape s{1, 2, 16, 5, 7};
  const attention_ref::Operands in = attention_ref::random_operands(ctx(), s, false, 0, 3600);
  const Pair q = operand(in.hq, s, s.q_len, DType::f16, false), k = operand(in.hk, s, s.kv_len, DType::f16, false),
             v = operand(in.hv, s, s.kv_len, DType::f16, false);
  const Tensor out = Tensor::zeros(ctx(), {1, 5, 32}, DType::f32);
  auto run = [&](const AttentionShape& sh, const AttentionOperand& qq, const AttentionOperand& kk,
                 const AttentionOperand& vv, const AttentionOperand& oo) {
    ops::run_now(ctx(), [&](vk::Recorder& rec) { ops::attention(rec, sh, qq, kk, vv, oo); });
  };
  {
    ops::ScopedTuningOverride texel("attention=texel");
    const AttentionOperand q32{in.q.t, 0, 0, true};  // f32 head-major alone
    expect_error([&] { run(s, q32, in.k, in.v, {out}); }, {"head-major operand", "texel kernel"});
  }
  ops::ScopedTuningOverride tiled("attention=tiled");
  // A head-major out; a head-major operand with a column offset.
  expect_error([&] { run(s, q.heads, k.heads, v.heads, {out, 0, 0, true}); }, {"out is head-major"});
  AttentionOperand shifted = k.heads;
  shifted.column_offset = 4;
  expect_error([&] { run(s, q.heads, shifted, v.heads, {out}); }, {"k is head-major", "column offset 4"});
  // head_dim 6 runs on padded token-major copies.
  const AttentionShape odd{1, 2, 6, 5, 7};
  const Tensor q6 = Tensor::zeros(ctx(), {1, 2, 5, 6}, DType::f32), kv6 = Tensor::zeros(ctx(), {1, 2, 7, 6}, DType::f32);
  expect_error([&] { run(odd, {q6, 0, 0, true}, {kv6, 0, 0, true}, {kv6, 0, 0, true}, {Tensor::zeros(ctx(), {1, 5, 12}, DType::f32)}); },
               {"head-major operand", "multiple of 4", "head_dim 6"});
}

}  // namespace
}  // namespace dvs::test
