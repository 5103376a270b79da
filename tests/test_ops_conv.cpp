// Convolutions and resampling (engine/src/tensor/ops_conv.*) against plain C++ references that follow
// diffusers step by step (pad the input explicitly, then a valid convolution in double).
//
// Weight dtypes f32/f16/bf16 are all exercised on the causal conv; the other kernels use bf16 (the real
// model's dtype) to keep the number of pipelines (seconds of LLVM compile each on lavapipe) down.
//
// Tolerances:
//  - convolutions: |gpu - ref| <= 1e-5 * sum_k |w_k x_k| + 1e-6 per output (fp32 accumulation of K terms;
//    weights stored f16/bf16 are widened exactly, so the reference uses the same rounded weights). Where the
//    tuning runs the tensor-core family (fp16 operands: each of x and w rounds by up to 2^-11 relative),
//    1e-3 * sum_k |w_k x_k| + 1e-6.
//  - the cache path, avg-pooling and nearest resampling: exact (bitwise equal).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "dvs/error.hpp"
#include "support/gpu.hpp"
#include "support/stored_values.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv.hpp"

namespace dvs {
namespace {

using test::GpuTest;

// A host video [B, C, F, H, W] in f32.
struct Vid {
  int64_t b = 1, c = 1, f = 1, h = 1, w = 1;
  std::vector<float> v;
  Vid() = default;
  Vid(int64_t b_, int64_t c_, int64_t f_, int64_t h_, int64_t w_) : b(b_), c(c_), f(f_), h(h_), w(w_), v(size_t(b * c * f * h * w)) {}
  float& at(int64_t bi, int64_t ci, int64_t fi, int64_t hi, int64_t wi) { return v[size_t((((bi * c + ci) * f + fi) * h + hi) * w + wi)]; }
  float at(int64_t bi, int64_t ci, int64_t fi, int64_t hi, int64_t wi) const { return v[size_t((((bi * c + ci) * f + fi) * h + hi) * w + wi)]; }
  Shape shape() const { return {b, c, f, h, w}; }
};

std::vector<float> random_values(size_t n, uint32_t seed, float lo = -1.f, float hi = 1.f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(lo, hi);
  std::vector<float> v(n);
  for (auto& x : v) x = d(rng);
  return v;
}

Vid random_vid(int64_t b, int64_t c, int64_t f, int64_t h, int64_t w, uint32_t seed) {
  Vid x(b, c, f, h, w);
  x.v = random_values(x.v.size(), seed);
  return x;
}

// Weights (or bias) stored as `dt`; `rounded` receives the values the GPU sees.
HostTensor make_weights(const Shape& s, DType dt, uint32_t seed, float scale, std::vector<float>& rounded) {
  rounded = random_values(size_t(shape_numel(s)), seed, -scale, scale);
  return test::stored_as(rounded, s, dt);
}

Tensor up(vk::Context& ctx, const Vid& x) { return Tensor::upload(ctx, HostTensor::from_f32(x.shape(), x.v)); }

Vid down(vk::Context& ctx, const Tensor& t) {
  HostTensor h = t.download(ctx);
  Vid r(t.dim(0), t.dim(1), t.dim(2), t.dim(3), t.dim(4));
  std::memcpy(r.v.data(), h.data.data(), h.data.size());
  return r;
}

// Explicit padding as diffusers does it: time prefix frames, then zero padding in H and W.
Vid pad_video(const Vid& x, const Vid* prefix, int64_t n_prefix, int64_t top, int64_t bottom, int64_t left, int64_t right) {
  Vid p(x.b, x.c, x.f + n_prefix, x.h + top + bottom, x.w + left + right);
  for (int64_t b = 0; b < x.b; ++b)
    for (int64_t c = 0; c < x.c; ++c)
      for (int64_t t = 0; t < p.f; ++t)
        for (int64_t i = 0; i < x.h; ++i)
          for (int64_t j = 0; j < x.w; ++j) {
            float v = t >= n_prefix ? x.at(b, c, t - n_prefix, i, j) : (prefix ? prefix->at(b, c, t, i, j) : x.at(b, c, 0, i, j));
            p.at(b, c, t, i + top, j + left) = v;
          }
  return p;
}

// Valid convolution of a padded video; returns outputs and, per output, sum |w x| for the tolerance.
struct ConvRef {
  Vid y, mag;
};
ConvRef valid_conv(const Vid& xp, const std::vector<float>& w, const std::vector<float>* bias, int64_t cout, int64_t kt,
                   int64_t kh, int64_t kw, int64_t stride) {
  int64_t fo = xp.f - kt + 1, ho = (xp.h - kh) / stride + 1, wo = (xp.w - kw) / stride + 1;
  ConvRef r{Vid(xp.b, cout, fo, ho, wo), Vid(xp.b, cout, fo, ho, wo)};
  for (int64_t b = 0; b < xp.b; ++b)
    for (int64_t o = 0; o < cout; ++o)
      for (int64_t t = 0; t < fo; ++t)
        for (int64_t i = 0; i < ho; ++i)
          for (int64_t j = 0; j < wo; ++j) {
            double s = bias ? (*bias)[size_t(o)] : 0.0, m = std::fabs(s);
            for (int64_t c = 0; c < xp.c; ++c)
              for (int64_t a = 0; a < kt; ++a)
                for (int64_t u = 0; u < kh; ++u)
                  for (int64_t v = 0; v < kw; ++v) {
                    double wv = w[size_t((((o * xp.c + c) * kt + a) * kh + u) * kw + v)];
                    double xv = xp.at(b, c, t + a, i * stride + u, j * stride + v);
                    s += wv * xv;
                    m += std::fabs(wv * xv);
                  }
            r.y.at(b, o, t, i, j) = float(s);
            r.mag.at(b, o, t, i, j) = float(m);
          }
  return r;
}

void expect_close(const Vid& got, const ConvRef& ref, const std::string& what) {
  ASSERT_EQ(got.v.size(), ref.y.v.size()) << what;
  size_t bad = 0;
  double worst = 0;
  const bool fp16_operands = ops::device_tuning(test::gpu().caps()).conv == ops::KernelFamily::coopmat;
  const double rel = fp16_operands ? 1e-3 : 1e-5;
  for (size_t i = 0; i < got.v.size(); ++i) {
    double err = std::fabs(double(got.v[i]) - ref.y.v[i]);
    double tol = rel * ref.mag.v[i] + 1e-6;
    worst = std::max(worst, err / tol);
    if (!(err <= tol) && bad++ < 3) ADD_FAILURE() << what << ": element " << i << " got " << got.v[i] << " expected " << ref.y.v[i];
  }
  EXPECT_EQ(bad, 0u) << what << " (worst error / tolerance " << worst << ")";
}

void expect_equal(const Vid& got, const Vid& want, const std::string& what) {
  ASSERT_EQ(got.shape(), want.shape()) << what;
  size_t bad = 0;
  for (size_t i = 0; i < got.v.size(); ++i)
    if (std::memcmp(&got.v[i], &want.v[i], 4) != 0 && bad++ < 3)
      ADD_FAILURE() << what << ": element " << i << " got " << got.v[i] << " expected " << want.v[i];
  EXPECT_EQ(bad, 0u) << what;
}

const char* dt_name(DType d) { return dtype_name(d); }

class ConvOps : public GpuTest {};

// ---- Conv2d per frame -----------------------------------------------------------------------------------

struct Conv2dCase {
  int64_t b, cin, cout, f, h, w, k;
  ops::Conv2dParams p;
  DType dt;
  bool bias;
};

void run_conv2d(vk::Context& ctx, const Conv2dCase& c, uint32_t seed) {
  Vid x = random_vid(c.b, c.cin, c.f, c.h, c.w, seed);
  std::vector<float> wr, br;
  float scale = 1.f / std::sqrt(float(c.cin * c.k * c.k));
  HostTensor wh = make_weights({c.cout, c.cin, c.k, c.k}, c.dt, seed + 1, scale, wr);
  HostTensor bh = make_weights({c.cout}, c.dt, seed + 2, 0.5f, br);
  Tensor xt = up(ctx, x), wt = Tensor::upload(ctx, wh), bt = Tensor::upload(ctx, bh);
  Shape ys = ops::conv2d_shape(xt.shape(), wt.shape(), c.p);
  Tensor yt = Tensor::empty(ctx, ys, DType::f32);
  ops::run_now(ctx, [&](vk::Recorder& rec) { ops::conv2d(rec, xt, wt, c.bias ? &bt : nullptr, yt, c.p); });

  ConvRef ref = valid_conv(pad_video(x, nullptr, 0, c.p.pad_top, c.p.pad_bottom, c.p.pad_left, c.p.pad_right), wr,
                           c.bias ? &br : nullptr, c.cout, 1, c.k, c.k, c.p.stride);
  HostTensor yh = yt.download(ctx);
  Vid got(ref.y.b, ref.y.c, ref.y.f, ref.y.h, ref.y.w);
  const float* g = yh.as<float>();
  for (int64_t b = 0; b < got.b; ++b)
    for (int64_t o = 0; o < got.c; ++o)
      for (int64_t t = 0; t < got.f; ++t)
        for (int64_t i = 0; i < got.h; ++i)
          for (int64_t j = 0; j < got.w; ++j) {
            size_t idx = c.p.channels_last_out ? size_t((((b * got.f + t) * got.h + i) * got.w + j) * got.c + o)
                                               : size_t((((b * got.c + o) * got.f + t) * got.h + i) * got.w + j);
            got.at(b, o, t, i, j) = g[idx];
          }
  std::string what = "conv2d k" + std::to_string(c.k) + " s" + std::to_string(c.p.stride) + " " + std::to_string(c.cin) +
                     "->" + std::to_string(c.cout) + " " + std::to_string(c.f) + "x" + std::to_string(c.h) + "x" +
                     std::to_string(c.w) + " " + dt_name(c.dt) + (c.bias ? " bias" : "") + (c.p.channels_last_out ? " tokens" : "");
  expect_close(got, ref, what);
}

TEST_F(ConvOps, Conv2dSame3x3) {
  uint32_t seed = 10;
  for (DType dt : {DType::f32, DType::bf16})
    run_conv2d(ctx(), {1, 3, 5, 2, 7, 9, 3, ops::Conv2dParams::same3x3(), dt, true}, seed++);
  run_conv2d(ctx(), {1, 1, 1, 1, 1, 1, 3, ops::Conv2dParams::same3x3(), DType::f32, false}, seed++);
  run_conv2d(ctx(), {2, 33, 9, 3, 17, 7, 3, ops::Conv2dParams::same3x3(), DType::bf16, true}, seed++);
  run_conv2d(ctx(), {1, 8, 33, 1, 9, 17, 3, ops::Conv2dParams::same3x3(), DType::f32, false}, seed++);
}

TEST_F(ConvOps, Conv2dPatchEmbedding) {
  uint32_t seed = 30;
  // [B, C, F, H, W] with channel-first output, and [N, C, H, W] (B*F frames) with token output.
  run_conv2d(ctx(), {1, 7, 9, 3, 8, 10, 2, ops::Conv2dParams::patch(false), DType::bf16, true}, seed++);
  run_conv2d(ctx(), {2, 32, 33, 2, 6, 10, 2, ops::Conv2dParams::patch(true), DType::bf16, true}, seed++);
  run_conv2d(ctx(), {1, 5, 3, 1, 7, 9, 2, ops::Conv2dParams::patch(true), DType::bf16, false}, seed++);  // odd sizes floor
}

TEST_F(ConvOps, Conv2dPatchEmbeddingOnImages) {
  // 4-D input [N, C, H, W] (the transformer's B*F latent frames), token output [N, Ho, Wo, Cout].
  vk::Context& c = ctx();
  Vid x = random_vid(3, 6, 1, 6, 8, 40);
  std::vector<float> wr, br;
  Tensor wt = Tensor::upload(c, make_weights({11, 6, 2, 2}, DType::bf16, 41, 0.3f, wr));
  Tensor bt = Tensor::upload(c, make_weights({11}, DType::bf16, 42, 0.3f, br));
  Tensor xt = Tensor::upload(c, HostTensor::from_f32({3, 6, 6, 8}, x.v));
  Tensor yt = Tensor::empty(c, {3, 3, 4, 11}, DType::f32);
  ops::run_now(c, [&](vk::Recorder& rec) { ops::conv2d(rec, xt, wt, &bt, yt, ops::Conv2dParams::patch()); });
  ConvRef ref = valid_conv(x, wr, &br, 11, 1, 2, 2, 2);
  std::vector<float> g = yt.download(c).to_f32();
  Vid got(3, 11, 1, 3, 4);
  for (int64_t n = 0; n < 3; ++n)
    for (int64_t o = 0; o < 11; ++o)
      for (int64_t i = 0; i < 3; ++i)
        for (int64_t j = 0; j < 4; ++j) got.at(n, o, 0, i, j) = g[size_t(((n * 3 + i) * 4 + j) * 11 + o)];
  expect_close(got, ref, "patch embedding on images");
}

TEST_F(ConvOps, Conv2dDownsample3x3Stride2) {
  uint32_t seed = 50;
  for (int64_t hw : {7, 8, 9, 17})
    run_conv2d(ctx(), {1, 4, 6, 2, hw, hw + 1, 3, ops::Conv2dParams::downsample3x3(), DType::bf16, true}, seed++);
  run_conv2d(ctx(), {1, 33, 17, 3, 9, 7, 3, ops::Conv2dParams::downsample3x3(), DType::bf16, true}, seed++);
  run_conv2d(ctx(), {1, 2, 3, 1, 2, 2, 3, ops::Conv2dParams::downsample3x3(), DType::bf16, false}, seed++);
}

// ---- Causal Conv3d --------------------------------------------------------------------------------------

struct Conv3dWeights {
  std::vector<float> w, bias;
  Tensor wt, bt;
};

Conv3dWeights make_conv3d(vk::Context& ctx, int64_t cout, int64_t cin, int64_t k, DType dt, uint32_t seed) {
  Conv3dWeights r;
  float scale = 1.f / std::sqrt(float(cin * k * k * k));
  r.wt = Tensor::upload(ctx, make_weights({cout, cin, k, k, k}, dt, seed, scale, r.w));
  r.bt = Tensor::upload(ctx, make_weights({cout}, dt, seed + 1, 0.5f, r.bias));
  return r;
}

// Reference: diffusers CogVideoXCausalConv3d.forward on one frame batch.
ConvRef causal_ref(const Vid& x, const Vid* cache, const Conv3dWeights& cw, int64_t cout, int64_t k, Vid* next_cache) {
  Vid tp = pad_video(x, cache, k - 1, 0, 0, 0, 0);
  if (next_cache) {
    *next_cache = Vid(x.b, x.c, k - 1, x.h, x.w);
    for (int64_t b = 0; b < x.b; ++b)
      for (int64_t c = 0; c < x.c; ++c)
        for (int64_t t = 0; t < k - 1; ++t)
          for (int64_t i = 0; i < x.h; ++i)
            for (int64_t j = 0; j < x.w; ++j) next_cache->at(b, c, t, i, j) = tp.at(b, c, tp.f - (k - 1) + t, i, j);
  }
  int64_t s = (k - 1) / 2;
  return valid_conv(pad_video(tp, nullptr, 0, s, s, s, s), cw.w, &cw.bias, cout, k, k, k, 1);
}

TEST_F(ConvOps, CausalConv3dFirstBatch) {
  vk::Context& c = ctx();
  struct Case {
    int64_t b, cin, cout, f, h, w;
    DType dt;
  };
  uint32_t seed = 70;
  for (Case k : {Case{1, 3, 5, 1, 7, 9, DType::f32}, Case{1, 4, 9, 2, 9, 7, DType::f16}, Case{2, 5, 3, 3, 7, 7, DType::bf16},
                 Case{1, 33, 17, 5, 9, 7, DType::bf16}, Case{1, 1, 1, 5, 1, 1, DType::f32}}) {
    Vid x = random_vid(k.b, k.cin, k.f, k.h, k.w, seed++);
    Conv3dWeights cw = make_conv3d(c, k.cout, k.cin, 3, k.dt, seed++);
    Tensor xt = up(c, x), yt = Tensor::empty(c, {k.b, k.cout, k.f, k.h, k.w}, DType::f32);
    Tensor cache = Tensor::empty(c, ops::causal_conv3d_cache_shape(xt.shape(), cw.wt.shape()), DType::f32);
    ops::run_now(c, [&](vk::Recorder& rec) { ops::causal_conv3d(rec, xt, cw.wt, &cw.bt, yt, nullptr, &cache); });
    Vid next;
    ConvRef ref = causal_ref(x, nullptr, cw, k.cout, 3, &next);
    std::string what = "causal_conv3d " + std::to_string(k.cin) + "->" + std::to_string(k.cout) + " F" + std::to_string(k.f) +
                       " " + dt_name(k.dt);
    expect_close(down(c, yt), ref, what);
    expect_equal(down(c, cache), next, what + " cache");
  }
}

// Running a clip in frame batches with the cache equals running it whole (and the diffusers reference).
TEST_F(ConvOps, CausalConv3dCacheMatchesWholeClip) {
  vk::Context& c = ctx();
  const int64_t bs = 2, cin = 6, cout = 7, h = 7, w = 9, frames = 5;
  Vid x = random_vid(bs, cin, frames, h, w, 90);
  Conv3dWeights cw = make_conv3d(c, cout, cin, 3, DType::bf16, 91);
  Tensor xt = up(c, x), whole = Tensor::empty(c, {bs, cout, frames, h, w}, DType::f32);
  ops::run_now(c, [&](vk::Recorder& rec) { ops::causal_conv3d(rec, xt, cw.wt, &cw.bt, whole, nullptr, nullptr); });
  Vid whole_h = down(c, whole);
  expect_close(whole_h, causal_ref(x, nullptr, cw, cout, 3, nullptr), "whole clip");

  // The encoder's 9-then-8 batching in miniature: uneven splits, single frames, one at a time.
  for (std::vector<int64_t> split : {std::vector<int64_t>{3, 2}, {1, 4}, {1, 1, 1, 1, 1}, {2, 3}}) {
    for (bool in_place : {false, true}) {
      Tensor cache_a = Tensor::empty(c, {bs, cin, 2, h, w}, DType::f32);
      Tensor cache_b = Tensor::empty(c, {bs, cin, 2, h, w}, DType::f32);
      int64_t first = 0, batch = 0;
      Vid ref_cache;
      for (int64_t n : split) {
        Vid part(bs, cin, n, h, w);
        for (int64_t bi = 0; bi < bs; ++bi)
          for (int64_t ci = 0; ci < cin; ++ci)
            for (int64_t t = 0; t < n; ++t)
              for (int64_t i = 0; i < h; ++i)
                for (int64_t j = 0; j < w; ++j) part.at(bi, ci, t, i, j) = x.at(bi, ci, first + t, i, j);
        Tensor pt = up(c, part), yt = Tensor::empty(c, {bs, cout, n, h, w}, DType::f32);
        // Ping-pong between two caches, or update one in place.
        const Tensor* cin_t = batch == 0 ? nullptr : (in_place || batch % 2 == 1 ? &cache_a : &cache_b);
        const Tensor* cout_t = in_place || batch % 2 == 0 ? &cache_a : &cache_b;
        ops::run_now(c, [&](vk::Recorder& rec) { ops::causal_conv3d(rec, pt, cw.wt, &cw.bt, yt, cin_t, cout_t); });
        Vid next;
        causal_ref(part, batch == 0 ? nullptr : &ref_cache, cw, cout, 3, &next);
        ref_cache = next;
        expect_equal(down(c, *cout_t), ref_cache, "cache after batch " + std::to_string(batch));
        Vid got = down(c, yt);
        for (int64_t bi = 0; bi < bs; ++bi)
          for (int64_t o = 0; o < cout; ++o)
            for (int64_t t = 0; t < n; ++t)
              for (int64_t i = 0; i < h; ++i)
                for (int64_t j = 0; j < w; ++j)
                  ASSERT_EQ(got.at(bi, o, t, i, j), whole_h.at(bi, o, first + t, i, j))
                      << "batch " << batch << " frame " << t << (in_place ? " in place" : " ping-pong");
        first += n;
        ++batch;
      }
    }
  }
}

// The register block and the lane scheme are specialization constants (tensor/kernel_tuning.cpp picks
// them per device): other choices, with partial tiles in pixels and channels, must give the same results.
// {16 x 2}: two shuffled 8-pixel groups; {4 x 4}: every lane fetches every pixel (few pixels);
// {8 x 2, lanes 2}: the variant without subgroup operations (conv_gemm_nosubgroup) that devices without
// shuffles run, so its pipeline is covered on lavapipe too; {8 x 3, k_unroll 2}: two 8-channel steps per
// loop trip (16 channels: one trip; the 12-channel case falls back to single steps).
TEST_F(ConvOps, OtherRegisterBlocks) {
  uint32_t seed = 100;
  for (ops::ConvRegisterBlock blk : {ops::ConvRegisterBlock{16, 2, -1, 0}, ops::ConvRegisterBlock{4, 4, -1, 0},
                                     ops::ConvRegisterBlock{8, 2, 2, 0}, ops::ConvRegisterBlock{8, 3, -1, 2}}) {
    ops::set_conv_register_block(blk);
    try {
      run_conv2d(ctx(), {1, 9, 21, 2, 9, 19, 3, ops::Conv2dParams::same3x3(), DType::bf16, true}, seed++);
      run_conv2d(ctx(), {1, 12, 5, 1, 9, 11, 3, ops::Conv2dParams::downsample3x3(), DType::f32, false}, seed++);
      run_conv2d(ctx(), {1, 16, 13, 1, 7, 9, 3, ops::Conv2dParams::same3x3(), DType::f16, true}, seed++);
    } catch (...) {
      ops::set_conv_register_block({});
      throw;
    }
  }
  ops::set_conv_register_block({});
}

// The four convolution paths that a split or a repack variant must leave bit-identical: the causal conv
// without and with a cache, the stride-2 downsample and the fused upsample + conv, on one random input.
struct FourConvs {
  vk::Context& c;
  int64_t b, cin, cout, f, h, w;
  bool compress_time;
  Vid x, cache;
  Conv3dWeights cw;
  std::vector<float> wr;
  Tensor w2, xt, ct;
  uint32_t dispatches = 0;  // of the last run: more chunks, more dispatches
  FourConvs(vk::Context& ctx, int64_t b_, int64_t cin_, int64_t cout_, int64_t f_, int64_t h_, int64_t w_, DType w2_dtype,
            bool compress_time_, uint32_t seed)
      : c(ctx), b(b_), cin(cin_), cout(cout_), f(f_), h(h_), w(w_), compress_time(compress_time_),
        x(random_vid(b, cin, f, h, w, seed)), cache(random_vid(b, cin, 2, h, w, seed + 1)),
        cw(make_conv3d(ctx, cout, cin, 3, DType::bf16, seed + 2)),
        w2(Tensor::upload(ctx, make_weights({cout, cin, 3, 3}, w2_dtype, seed + 3, 0.2f, wr))), xt(up(ctx, x)),
        ct(up(ctx, cache)) {}
  std::vector<Vid> run() {
    Shape down_s = ops::conv2d_shape(xt.shape(), w2.shape(), ops::Conv2dParams::downsample3x3());
    Shape up_s = ops::upsample2x_shape(xt.shape(), compress_time);
    up_s[1] = cout;
    Tensor y1 = Tensor::empty(c, {b, cout, f, h, w}, DType::f32), y2 = Tensor::empty(c, y1.shape(), DType::f32);
    Tensor y3 = Tensor::empty(c, down_s, DType::f32), y4 = Tensor::empty(c, up_s, DType::f32);
    ops::run_now(c, [&](vk::Recorder& rec) {
      ops::causal_conv3d(rec, xt, cw.wt, &cw.bt, y1);
      ops::causal_conv3d(rec, xt, cw.wt, &cw.bt, y2, &ct);
      ops::conv2d(rec, xt, w2, nullptr, y3, ops::Conv2dParams::downsample3x3());
      ops::upsample2x_conv3x3(rec, xt, w2, nullptr, y4, compress_time);
      dispatches = rec.dispatch_count();
    });
    std::vector<Vid> r;
    for (const Tensor* t : {&y1, &y2, &y3, &y4}) r.push_back(down(c, *t));
    return r;
  }
  // The causal convs against the independent reference.
  void expect_reference(const std::vector<Vid>& got, const std::string& what) {
    expect_close(got[0], causal_ref(x, nullptr, cw, cout, 3, nullptr), "causal conv, " + what);
    expect_close(got[1], causal_ref(x, &cache, cw, cout, 3, nullptr), "causal conv with cache, " + what);
  }
  static void expect_same(const std::vector<Vid>& got, const std::vector<Vid>& want, const std::string& what) {
    const char* names[] = {"causal conv", "causal conv with cache", "stride 2", "upsample + conv"};
    for (size_t i = 0; i < got.size(); ++i) expect_equal(got[i], want[i], std::string(names[i]) + ", " + what);
  }
};

// Large inputs are split into chunks of output frames, and single frames into chunks of output rows,
// each repacked separately (set_conv_chunk_bytes forces the splits the real size needs). Every split must
// give the unsplit result bit for bit (same values, same summation order), which the tests above check
// against the references: frame chunks with the causal prefix and with a cache, row chunks with padding
// rows at both ends, stride 2 (chunk borders on odd input rows) and the fused upsampling (row chunks of
// the upsampled image).
TEST_F(ConvOps, SplitsOverFramesAndRows) {
  vk::Context& c = ctx();
  struct Reset {
    ~Reset() { ops::set_conv_chunk_bytes(0); }
  } reset;
  const int64_t cin = 12, cout = 9, f = 5, h = 11, w = 9;  // every tensor within the tiny alloc limit (256 KiB)
  FourConvs convs(c, 2, cin, cout, f, h, w, DType::bf16, true, 130);
  std::vector<Vid> whole = convs.run();
  convs.expect_reference(whole, "unsplit");
  uint32_t previous = convs.dispatches;
  const int64_t cp_bytes = 16 * int64_t(dtype_size(ops::conv_repack_dtype(c.caps())));  // 12 channels pad to 16
  // One frame of the padded axis is h*w pixels: room for 4 padded frames (2 output frames + the prefix),
  // then for 9 source rows of padded frames (the causal conv: 3 frames x 3 rows = one output row per chunk).
  for (int64_t budget : {4 * h * w * cp_bytes + cp_bytes, 9 * w * cp_bytes + cp_bytes}) {
    ops::set_conv_chunk_bytes(uint64_t(budget));
    FourConvs::expect_same(convs.run(), whole, "split at " + std::to_string(budget) + " bytes");
    if (uint64_t(budget) < c.caps().max_storage_buffer_range) {  // else the limits in force (DVS_LIMITS) split already
      EXPECT_GT(convs.dispatches, previous) << "the budget of " << budget << " bytes did not split the convolutions further";
    }
    previous = convs.dispatches;
  }
  // A budget below one row of one frame cannot be met: a clear error, not a wrong result.
  ops::set_conv_chunk_bytes(uint64_t(w * cp_bytes));
  Tensor y = Tensor::empty(c, {2, cout, f, h, w}, DType::f32);
  EXPECT_THROW(ops::run_now(c, [&](vk::Recorder& rec) { ops::causal_conv3d(rec, convs.xt, convs.cw.wt, &convs.cw.bt, y); }),
               Error);
}

// The input repack writes `pack_columns` pixels of a row per invocation (kernel_tuning.cpp: whole rows on
// CPU drivers, a few pixels on GPUs): segment lengths that divide the row or not, alone and with the row and
// column chunks of a split, must give the whole-row result bit for bit (a wrong segment start or end would
// leave pixels unpacked or shifted).
TEST_F(ConvOps, InputRepackSegments) {
  struct Reset {
    ~Reset() {
      ops::set_conv_chunk_bytes(0);
      ops::set_conv_register_block({});
    }
  } reset;
  FourConvs convs(ctx(), 1, 5, 7, 3, 6, 11, DType::f32, false, 140);
  ops::set_conv_register_block({0, 0, -1, 0, 1000});  // whole rows
  std::vector<Vid> whole = convs.run();
  convs.expect_reference(whole, "whole-row repack");
  const int64_t cp_bytes = 8 * int64_t(dtype_size(ops::conv_repack_dtype(ctx().caps())));  // 5 channels pad to 8
  for (int64_t budget : {int64_t(0), 9 * 4 * cp_bytes + cp_bytes}) {  // unsplit; 3 frames x 3 rows x 4 columns
    ops::set_conv_chunk_bytes(uint64_t(budget));
    for (int seg : {1, 3, 4, 11}) {
      ops::set_conv_register_block({0, 0, -1, 0, seg});
      FourConvs::expect_same(convs.run(), whole,
                             std::to_string(seg) + " pixels per repack invocation" + (budget ? ", split" : ""));
    }
  }
}

// Caller-provided staging (what the VAE passes so that its memory plan counts it): buffers of the sizes
// *_scratch() gives are enough and give the recorder-scratch result bit for bit; a weights buffer one
// element short makes the op repack its weights per group of output channels (same sums, bit for bit).
TEST_F(ConvOps, CallerScratch) {
  vk::Context& c = ctx();
  Vid x = random_vid(1, 12, 3, 9, 11, 140);
  Conv3dWeights cw = make_conv3d(c, 10, 12, 3, DType::f32, 141);
  std::vector<float> wr;
  Tensor w2 = Tensor::upload(c, make_weights({10, 12, 3, 3}, DType::bf16, 142, 0.2f, wr));
  Tensor xt = up(c, x), ct = up(c, random_vid(1, 12, 2, 9, 11, 143));
  Shape up_s = ops::upsample2x_shape(xt.shape(), true);
  up_s[1] = 10;
  auto run = [&](bool given, int64_t weights_short) {
    ops::ConvScratchSize s3 = ops::causal_conv3d_scratch(xt.shape(), cw.wt.shape());
    ops::ConvScratchSize s2 = ops::conv2d_scratch(xt.shape(), w2.shape());
    ops::ConvScratchSize su = ops::upsample2x_conv3x3_scratch(xt.shape(), w2.shape(), true);
    ops::ConvScratch a{Tensor::empty(c, {s3.input}, DType::f32), Tensor::empty(c, {s3.weights - weights_short}, DType::f32)};
    ops::ConvScratch b{Tensor::empty(c, {s2.input}, DType::f32), Tensor::empty(c, {s2.weights}, DType::f32)};
    ops::ConvScratch u{Tensor::empty(c, {su.input}, DType::f32), Tensor::empty(c, {su.weights}, DType::f32)};
    Tensor y1 = Tensor::empty(c, {1, 10, 3, 9, 11}, DType::f32), y2 = Tensor::empty(c, y1.shape(), DType::f32);
    Tensor y3 = Tensor::empty(c, y1.shape(), DType::f32), y4 = Tensor::empty(c, up_s, DType::f32);
    ops::run_now(c, [&](vk::Recorder& rec) {
      ops::causal_conv3d(rec, xt, cw.wt, &cw.bt, y1, &ct, nullptr, given ? &a : nullptr);
      ops::conv2d(rec, xt, w2, nullptr, y3, ops::Conv2dParams::same3x3(), given ? &b : nullptr);
      ops::upsample2x_conv3x3(rec, xt, w2, nullptr, y4, true, given ? &u : nullptr);
    });
    return std::vector<Vid>{down(c, y1), down(c, y3), down(c, y4)};
  };
  std::vector<Vid> own = run(false, 0), given = run(true, 0);
  for (size_t i = 0; i < own.size(); ++i) expect_equal(given[i], own[i], "caller scratch, op " + std::to_string(i));
  std::vector<Vid> grouped = run(true, 1);
  for (size_t i = 0; i < own.size(); ++i) expect_equal(grouped[i], own[i], "short weights scratch, op " + std::to_string(i));
}

TEST_F(ConvOps, Conv1x1) {
  vk::Context& c = ctx();
  uint32_t seed = 110;
  for (auto [cin, cout, f, h, w] : std::vector<std::array<int64_t, 5>>{{1, 1, 1, 1, 1}, {7, 33, 3, 7, 9}, {33, 5, 2, 9, 17}}) {
    for (DType dt : {DType::bf16}) {
      Vid x = random_vid(1, cin, f, h, w, seed++);
      std::vector<float> wr, br;
      Tensor wt = Tensor::upload(c, make_weights({cout, cin, 1, 1, 1}, dt, seed++, 0.5f, wr));
      Tensor bt = Tensor::upload(c, make_weights({cout}, dt, seed++, 0.5f, br));
      Tensor xt = up(c, x), yt = Tensor::empty(c, {1, cout, f, h, w}, DType::f32);
      ops::run_now(c, [&](vk::Recorder& rec) { ops::conv1x1(rec, xt, wt, &bt, yt); });
      expect_close(down(c, yt), valid_conv(x, wr, &br, cout, 1, 1, 1, 1), "conv1x1 " + std::to_string(cin) + "->" + std::to_string(cout));
    }
  }
}

// ---- Resampling -----------------------------------------------------------------------------------------

TEST_F(ConvOps, AvgPoolTimePairs) {
  vk::Context& c = ctx();
  // 7x9 planes take the scalar kernel, 4x6 planes (a multiple of 4) the vec4 one.
  for (auto [h, w] : std::vector<std::pair<int64_t, int64_t>>{{7, 9}, {4, 6}})
    for (int64_t f : {1, 2, 3, 4, 5, 9}) {
      Vid x = random_vid(2, 3, f, h, w, uint32_t(130 + f));
      int64_t fo = ops::downsample_time_frames(f);
      EXPECT_EQ(fo, f % 2 ? (f + 1) / 2 : f / 2);
      Vid want(2, 3, fo, h, w);
      for (int64_t b = 0; b < 2; ++b)
        for (int64_t ch = 0; ch < 3; ++ch)
          for (int64_t t = 0; t < fo; ++t)
            for (int64_t i = 0; i < h; ++i)
              for (int64_t j = 0; j < w; ++j) {
                // diffusers: odd -> [x0, avg_pool1d(x[1:])], even -> avg_pool1d(x)
                int64_t first = f % 2 ? 2 * t - 1 : 2 * t;
                want.at(b, ch, t, i, j) = (f % 2 && t == 0) ? x.at(b, ch, 0, i, j)
                                                            : (x.at(b, ch, first, i, j) + x.at(b, ch, first + 1, i, j)) / 2.f;
              }
      Tensor xt = up(c, x), yt = Tensor::empty(c, want.shape(), DType::f32);
      ops::run_now(c, [&](vk::Recorder& rec) { ops::avgpool_time_pairs(rec, xt, yt); });
      expect_equal(down(c, yt), want, "avgpool_time F=" + std::to_string(f) + " plane " + std::to_string(h * w));
    }
}

// PyTorch's nearest index: floor(dst * (in / out)) in fp32, clamped.
int64_t torch_nearest(int64_t dst, int64_t n_in, int64_t n_out) {
  float scale = float(n_in) / float(n_out);
  return std::min<int64_t>(int64_t(std::floor(float(dst) * scale)), n_in - 1);
}

Vid nearest_ref(const Vid& x, int64_t fo, int64_t ho, int64_t wo, bool keep_first) {
  Vid y(x.b, x.c, fo, ho, wo);
  for (int64_t b = 0; b < x.b; ++b)
    for (int64_t c = 0; c < x.c; ++c)
      for (int64_t t = 0; t < fo; ++t)
        for (int64_t i = 0; i < ho; ++i)
          for (int64_t j = 0; j < wo; ++j) {
            int64_t st = keep_first ? (t == 0 ? 0 : 1 + torch_nearest(t - 1, x.f - 1, fo - 1)) : torch_nearest(t, x.f, fo);
            y.at(b, c, t, i, j) = x.at(b, c, st, torch_nearest(i, x.h, ho), torch_nearest(j, x.w, wo));
          }
  return y;
}

TEST_F(ConvOps, Upsample2xSpatialAndTemporal) {
  vk::Context& c = ctx();
  for (bool ct : {false, true})
    for (int64_t f : {1, 2, 3, 4, 5}) {
      Vid x = random_vid(1, 5, f, 7, 9, uint32_t(150 + f));
      Shape ys = ops::upsample2x_shape(x.shape(), ct);
      // CogVideoXUpsample3D: odd F > 1 -> 1 + 2(F-1); even F -> 2F; F = 1 -> 1 (time only with compress_time).
      int64_t want_f = !ct || f == 1 ? f : (f % 2 ? 1 + 2 * (f - 1) : 2 * f);
      ASSERT_EQ(ys, (Shape{1, 5, want_f, 14, 18}));
      Vid want(1, 5, want_f, 14, 18);
      for (int64_t ch = 0; ch < 5; ++ch)
        for (int64_t t = 0; t < want_f; ++t)
          for (int64_t i = 0; i < 14; ++i)
            for (int64_t j = 0; j < 18; ++j) {
              int64_t st = t;
              if (ct && f > 1) st = f % 2 ? (t == 0 ? 0 : 1 + (t - 1) / 2) : t / 2;
              want.at(0, ch, t, i, j) = x.at(0, ch, st, i / 2, j / 2);
            }
      Tensor xt = up(c, x), yt = Tensor::empty(c, ys, DType::f32);
      ops::run_now(c, [&](vk::Recorder& rec) { ops::upsample2x(rec, xt, yt, ct); });
      expect_equal(down(c, yt), want, std::string("upsample2x F=") + std::to_string(f) + (ct ? " compress_time" : ""));
    }
}

// CogVideoXUpsample3D fused: equal (bitwise: same values, same summation order) to upsample2x followed
// by conv2d 3x3 pad 1, which the tests above check against the references.
TEST_F(ConvOps, Upsample2xConv3x3Fused) {
  vk::Context& c = ctx();
  std::vector<float> wr, br;
  Tensor wt = Tensor::upload(c, make_weights({7, 5, 3, 3}, DType::bf16, 190, 0.2f, wr));
  Tensor bt = Tensor::upload(c, make_weights({7}, DType::bf16, 191, 0.2f, br));
  for (bool ct : {false, true})
    for (int64_t f : {1, 2, 3}) {
      Vid x = random_vid(2, 5, f, 7, 9, uint32_t(192 + f));
      Tensor xt = up(c, x);
      Shape us = ops::upsample2x_shape(xt.shape(), ct);
      Tensor u = Tensor::empty(c, us, DType::f32);
      Tensor y1 = Tensor::empty(c, {us[0], 7, us[2], us[3], us[4]}, DType::f32);
      Tensor y2 = Tensor::empty(c, y1.shape(), DType::f32);
      ops::run_now(c, [&](vk::Recorder& rec) {
        ops::upsample2x(rec, xt, u, ct);
        ops::conv2d(rec, u, wt, &bt, y1, ops::Conv2dParams::same3x3());
        ops::upsample2x_conv3x3(rec, xt, wt, &bt, y2, ct);
      });
      expect_equal(down(c, y2), down(c, y1), std::string("upsample2x_conv3x3 F=") + std::to_string(f) + (ct ? " compress_time" : ""));
    }
}

TEST_F(ConvOps, UpsampleNearestAnySize) {
  // SpatialNorm-style resize of zq to a feature map (first frame separate) and non-integer ratios.
  vk::Context& c = ctx();
  struct Case {
    int64_t f, h, w, fo, ho, wo;
    bool keep_first;
  };
  uint32_t seed = 170;
  for (Case k : {Case{3, 3, 5, 5, 12, 20, true}, Case{3, 3, 5, 9, 6, 10, true}, Case{2, 7, 9, 4, 10, 13, false},
                 Case{1, 4, 4, 1, 9, 7, false}, Case{5, 9, 7, 3, 4, 5, false}}) {
    Vid x = random_vid(2, 3, k.f, k.h, k.w, seed++);
    Tensor xt = up(c, x), yt = Tensor::empty(c, {2, 3, k.fo, k.ho, k.wo}, DType::f32);
    ops::run_now(c, [&](vk::Recorder& rec) { ops::upsample_nearest(rec, xt, yt, k.keep_first); });
    expect_equal(down(c, yt), nearest_ref(x, k.fo, k.ho, k.wo, k.keep_first), "upsample_nearest");
  }
}

TEST_F(ConvOps, RejectsBadShapes) {
  vk::Context& c = ctx();
  Tensor x = Tensor::empty(c, {1, 4, 2, 5, 5}, DType::f32);
  Tensor w = Tensor::empty(c, {3, 5, 3, 3, 3}, DType::f32);  // Cin mismatch
  Tensor y = Tensor::empty(c, {1, 3, 2, 5, 5}, DType::f32);
  vk::Recorder rec(c);
  rec.begin();
  EXPECT_THROW(ops::causal_conv3d(rec, x, w, nullptr, y), Error);
  Tensor w2 = Tensor::empty(c, {3, 4, 3, 3, 3}, DType::f32);
  Tensor bad_cache = Tensor::empty(c, {1, 4, 1, 5, 5}, DType::f32);
  EXPECT_THROW(ops::causal_conv3d(rec, x, w2, nullptr, y, &bad_cache), Error);
  Tensor bad_y = Tensor::empty(c, {1, 3, 2, 4, 5}, DType::f32);
  EXPECT_THROW(ops::causal_conv3d(rec, x, w2, nullptr, bad_y), Error);
  Tensor wi = Tensor::empty(c, {3, 4, 3, 3, 3}, DType::i32);
  EXPECT_THROW(ops::causal_conv3d(rec, x, wi, nullptr, y), Error);
  rec.end();
}

}  // namespace
}  // namespace dvs
