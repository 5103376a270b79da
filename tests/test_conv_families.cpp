// The GPU families of the convolutions (engine/src/tensor/kernel_tuning.hpp), forced on whatever device
// runs the tests: "tiled" (shaders/nn/conv_tiled.comp, shared-memory tiles over storage buffers, fp32) at
// several workgroup tiles, and the tiling / loads / fp16 rounding / epilogue of "coopmat" through its fp32
// twin (nn/conv_coopmat_twin, from shaders/nn/conv_coopmat.comp; the tensor-core product cannot run on lavapipe).
// Every conv variant the models use, with odd channel counts (Cin 3, 5, 13, 37, and 32, 64 for whole-tap steps;
// Cout 3, 7, 19, 40, 140) and odd frame / row / column counts, against a plain-C++ reference written out here
// (explicit time prefix, nearest x2 upsampling and zero padding, then a valid convolution in double).
// Tolerances: |gpu - ref| <= 1e-5 * sum_k |w_k x_k| + 1e-6 (fp32 accumulation); for the coopmat twin the
// reference uses x and w rounded to fp16 as the kernel does, so the same bound holds.
// The existing suites (ConvOps.*, SplitConv.*: caches, splits under forced limits) also run against the
// tiled family as the ctest entries conv_tiled_family.* (tests/CMakeLists.txt, DVS_TUNING=conv=tiled).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <random>
#include <string>
#include <vector>

#include "io/host_tensor.hpp"
#include "support/gpu.hpp"
#include "support/stored_values.hpp"
#include "tensor/coopmat_layout.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv.hpp"
#include "vk/pipeline.hpp"

namespace dvs {
namespace {

using test::GpuTest;

struct Video {  // host [B, C, F, H, W]
  int64_t b = 0, c = 0, f = 0, h = 0, w = 0;
  std::vector<float> v;
  Video() = default;
  Video(int64_t b_, int64_t c_, int64_t f_, int64_t h_, int64_t w_) : b(b_), c(c_), f(f_), h(h_), w(w_), v(size_t(b * c * f * h * w)) {}
  float& at(int64_t i, int64_t ci, int64_t t, int64_t y, int64_t x) { return v[size_t((((i * c + ci) * f + t) * h + y) * w + x)]; }
  float at(int64_t i, int64_t ci, int64_t t, int64_t y, int64_t x) const { return v[size_t((((i * c + ci) * f + t) * h + y) * w + x)]; }
};

std::vector<float> randoms(size_t n, uint32_t seed, float scale) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(-scale, scale);
  std::vector<float> v(n);
  for (float& x : v) x = d(rng);
  return v;
}

Video random_video(int64_t b, int64_t c, int64_t f, int64_t h, int64_t w, uint32_t seed) {
  Video x(b, c, f, h, w);
  x.v = randoms(x.v.size(), seed, 1.f);
  return x;
}

float round_f16(float v) { return f16_to_f32(f32_to_f16(v)); }

// Weights or bias stored as `dt`; `seen` receives the values the kernel reads.
HostTensor stored(const Shape& s, DType dt, uint32_t seed, float scale, std::vector<float>& seen) {
  seen = randoms(size_t(shape_numel(s)), seed, scale);
  return test::stored_as(seen, s, dt);
}

// The time prefix (P frames: the cache, else copies of frame 0), then zero padding in H and W.
Video pad(const Video& x, const Video* cache, int64_t prefix, int64_t top, int64_t bottom, int64_t left, int64_t right) {
  Video p(x.b, x.c, x.f + prefix, x.h + top + bottom, x.w + left + right);
  for (int64_t i = 0; i < x.b; ++i)
    for (int64_t c = 0; c < x.c; ++c)
      for (int64_t t = 0; t < p.f; ++t)
        for (int64_t y = 0; y < x.h; ++y)
          for (int64_t z = 0; z < x.w; ++z)
            p.at(i, c, t, y + top, z + left) = t >= prefix ? x.at(i, c, t - prefix, y, z) : cache ? cache->at(i, c, t, y, z) : x.at(i, c, 0, y, z);
  return p;
}

// CogVideoXUpsample3D's nearest x2: H and W doubled; with compress_time frames doubled too, except frame 0
// of an odd count > 1, which stays single.
Video upsample(const Video& x, bool compress_time) {
  std::vector<int64_t> src;
  for (int64_t t = 0; t < x.f; ++t) {
    if (compress_time && x.f > 1 && !(x.f % 2 == 1 && t == 0)) src.push_back(t);
    src.push_back(t);
  }
  Video u(x.b, x.c, int64_t(src.size()), 2 * x.h, 2 * x.w);
  for (int64_t i = 0; i < x.b; ++i)
    for (int64_t c = 0; c < x.c; ++c)
      for (int64_t t = 0; t < u.f; ++t)
        for (int64_t y = 0; y < u.h; ++y)
          for (int64_t z = 0; z < u.w; ++z) u.at(i, c, t, y, z) = x.at(i, c, src[size_t(t)], y / 2, z / 2);
  return u;
}

struct Ref {
  Video y, mag;  // outputs, and sum |w x| per output (the tolerance)
};
// Valid convolution of a padded video in double; `round` rounds x and w as fp16 tensor-core operands.
Ref valid(const Video& xp, const std::vector<float>& w, const std::vector<float>* bias, int64_t cout, int64_t kt, int64_t kh,
          int64_t kw, int64_t stride, bool round) {
  const int64_t fo = xp.f - kt + 1, ho = (xp.h - kh) / stride + 1, wo = (xp.w - kw) / stride + 1;
  Ref r{Video(xp.b, cout, fo, ho, wo), Video(xp.b, cout, fo, ho, wo)};
  auto rd = [&](float v) { return double(round ? round_f16(v) : v); };
  for (int64_t i = 0; i < xp.b; ++i)
    for (int64_t o = 0; o < cout; ++o)
      for (int64_t t = 0; t < fo; ++t)
        for (int64_t y = 0; y < ho; ++y)
          for (int64_t z = 0; z < wo; ++z) {
            double s = bias ? (*bias)[size_t(o)] : 0.0, m = std::fabs(s);
            for (int64_t c = 0; c < xp.c; ++c)
              for (int64_t a = 0; a < kt; ++a)
                for (int64_t u = 0; u < kh; ++u)
                  for (int64_t v = 0; v < kw; ++v) {
                    double p = rd(w[size_t((((o * xp.c + c) * kt + a) * kh + u) * kw + v)]) * rd(xp.at(i, c, t + a, y * stride + u, z * stride + v));
                    s += p;
                    m += std::fabs(p);
                  }
            r.y.at(i, o, t, y, z) = float(s);
            r.mag.at(i, o, t, y, z) = float(m);
          }
  return r;
}

// y downloaded into [B, C, F, H, W] order (from the token layout [B, F, H, W, C] when channels_last).
Video fetch(vk::Context& c, const Tensor& y, const Ref& like, bool channels_last) {
  std::vector<float> g = y.download(c).to_f32();
  Video r = like.y;
  for (int64_t i = 0; i < r.b; ++i)
    for (int64_t o = 0; o < r.c; ++o)
      for (int64_t t = 0; t < r.f; ++t)
        for (int64_t h = 0; h < r.h; ++h)
          for (int64_t z = 0; z < r.w; ++z)
            r.at(i, o, t, h, z) = g[size_t(channels_last ? ((((i * r.f + t) * r.h + h) * r.w + z) * r.c + o)
                                                         : ((((i * r.c + o) * r.f + t) * r.h + h) * r.w + z))];
  return r;
}

void expect_close(const Video& got, const Ref& ref, const std::string& what) {
  ASSERT_EQ(got.v.size(), ref.y.v.size()) << what;
  size_t bad = 0;
  double worst = 0;
  for (size_t i = 0; i < got.v.size(); ++i) {
    const double err = std::fabs(double(got.v[i]) - ref.y.v[i]), tol = 1e-5 * ref.mag.v[i] + 1e-6;
    worst = std::max(worst, err / tol);
    if (!(err <= tol) && bad++ < 3) ADD_FAILURE() << what << ": element " << i << " got " << got.v[i] << " expected " << ref.y.v[i];
  }
  EXPECT_EQ(bad, 0u) << what << " (worst error / tolerance " << worst << ")";
}

// One convolution of the models: conv2d (3x3 same, 2x2 patch with token output, stride-2 downsample),
// causal conv3d (first batch / with a cache), 1x1, fused upsample x2 + 3x3.
enum class Kind { same3x3, patch_tokens, patch_images, downsample, causal, causal_cached, pointwise, upsample_conv };
struct Case {
  Kind kind;
  int64_t b, cin, cout, f, h, w;
  DType dt;
  bool bias = true;
  bool compress_time = false;
};

std::string describe(const Case& k) {
  static const char* names[] = {"conv2d 3x3", "patch (tokens)", "patch on images", "downsample 3x3 s2",
                                "causal conv3d", "causal conv3d with cache", "conv 1x1", "upsample x2 + conv 3x3"};
  return std::string(names[int(k.kind)]) + " " + std::to_string(k.cin) + "->" + std::to_string(k.cout) + " B" +
         std::to_string(k.b) + " F" + std::to_string(k.f) + " " + std::to_string(k.h) + "x" + std::to_string(k.w) + " " +
         dtype_name(k.dt) + (k.bias ? " bias" : "") + (k.compress_time ? " compress_time" : "");
}

// Runs one case on the device and checks it against the reference (and the cache update, exactly).
void check(vk::Context& c, const Case& k, uint32_t seed, bool fp16_operands, const std::string& family) {
  const std::string what = family + ": " + describe(k);
  SCOPED_TRACE(what);
  Video x = random_video(k.b, k.cin, k.f, k.h, k.w, seed);
  const bool conv3d = k.kind == Kind::causal || k.kind == Kind::causal_cached;
  const int64_t kt = conv3d ? 3 : 1, ks = k.kind == Kind::pointwise ? 1 : (k.kind == Kind::patch_tokens || k.kind == Kind::patch_images) ? 2 : 3;
  Shape ws = conv3d ? Shape{k.cout, k.cin, 3, 3, 3} : k.kind == Kind::pointwise ? Shape{k.cout, k.cin, 1, 1, 1} : Shape{k.cout, k.cin, ks, ks};
  std::vector<float> wv, bv;
  Tensor wt = Tensor::upload(c, stored(ws, k.dt, seed + 1, 1.f / std::sqrt(float(k.cin * kt * ks * ks)), wv));
  Tensor bt = Tensor::upload(c, stored({k.cout}, k.dt, seed + 2, 0.5f, bv));
  const Tensor* b = k.bias ? &bt : nullptr;
  const std::vector<float>* bref = k.bias ? &bv : nullptr;
  Tensor xt = k.kind == Kind::patch_images ? Tensor::upload(c, HostTensor::from_f32({k.b * k.f, k.cin, k.h, k.w}, x.v))
                                           : Tensor::upload(c, HostTensor::from_f32({k.b, k.cin, k.f, k.h, k.w}, x.v));
  Ref ref;
  Tensor yt;
  bool tokens = false;
  switch (k.kind) {
    case Kind::same3x3:
    case Kind::patch_tokens:
    case Kind::patch_images:
    case Kind::downsample: {
      ops::Conv2dParams p = k.kind == Kind::same3x3      ? ops::Conv2dParams::same3x3()
                            : k.kind == Kind::downsample ? ops::Conv2dParams::downsample3x3()
                                                         : ops::Conv2dParams::patch(true);
      tokens = p.channels_last_out;
      Video xr = x;
      if (k.kind == Kind::patch_images) xr.b = k.b * k.f, xr.f = 1;  // [N, C, H, W]: frames as batch items
      ref = valid(pad(xr, nullptr, 0, p.pad_top, p.pad_bottom, p.pad_left, p.pad_right), wv, bref, k.cout, 1, ks, ks, p.stride, fp16_operands);
      yt = Tensor::empty(c, ops::conv2d_shape(xt.shape(), wt.shape(), p), DType::f32);
      ops::run_now(c, [&](vk::Recorder& rec) { ops::conv2d(rec, xt, wt, b, yt, p); });
      break;
    }
    case Kind::causal:
    case Kind::causal_cached: {
      Video cache = random_video(k.b, k.cin, 2, k.h, k.w, seed + 3);
      const bool cached = k.kind == Kind::causal_cached;
      Tensor ct = Tensor::upload(c, HostTensor::from_f32({k.b, k.cin, 2, k.h, k.w}, cache.v));
      Tensor next = Tensor::empty(c, {k.b, k.cin, 2, k.h, k.w}, DType::f32);
      Video xp = pad(x, cached ? &cache : nullptr, 2, 0, 0, 0, 0);
      ref = valid(pad(xp, nullptr, 0, 1, 1, 1, 1), wv, bref, k.cout, 3, 3, 3, 1, fp16_operands);
      yt = Tensor::empty(c, {k.b, k.cout, k.f, k.h, k.w}, DType::f32);
      ops::run_now(c, [&](vk::Recorder& rec) { ops::causal_conv3d(rec, xt, wt, b, yt, cached ? &ct : nullptr, &next); });
      std::vector<float> got = next.download(c).to_f32();
      Video want(k.b, k.cin, 2, k.h, k.w);
      for (int64_t i = 0; i < k.b; ++i)
        for (int64_t ci = 0; ci < k.cin; ++ci)
          for (int64_t t = 0; t < 2; ++t)
            for (int64_t y = 0; y < k.h; ++y)
              for (int64_t z = 0; z < k.w; ++z) want.at(i, ci, t, y, z) = xp.at(i, ci, xp.f - 2 + t, y, z);
      EXPECT_EQ(std::memcmp(got.data(), want.v.data(), got.size() * 4), 0) << what << ": cache_out";
      break;
    }
    case Kind::pointwise:
      ref = valid(x, wv, bref, k.cout, 1, 1, 1, 1, fp16_operands);
      yt = Tensor::empty(c, {k.b, k.cout, k.f, k.h, k.w}, DType::f32);
      ops::run_now(c, [&](vk::Recorder& rec) { ops::conv1x1(rec, xt, wt, b, yt); });
      break;
    case Kind::upsample_conv: {
      ref = valid(pad(upsample(x, k.compress_time), nullptr, 0, 1, 1, 1, 1), wv, bref, k.cout, 1, 3, 3, 1, fp16_operands);
      Shape us = ops::upsample2x_shape(xt.shape(), k.compress_time);
      yt = Tensor::empty(c, {us[0], k.cout, us[2], us[3], us[4]}, DType::f32);
      ops::run_now(c, [&](vk::Recorder& rec) { ops::upsample2x_conv3x3(rec, xt, wt, b, yt, k.compress_time); });
      break;
    }
  }
  // (patch on images: y [N, Ho, Wo, Cout] is the token layout with one frame per batch item)
  expect_close(fetch(c, yt, ref, tokens), ref, what);
}

// Every variant, odd sizes; several workgroups along pixels and channels in the last cases.
std::vector<Case> all_cases() {
  return {
      {Kind::same3x3, 1, 3, 7, 2, 7, 9, DType::f32},
      {Kind::same3x3, 2, 13, 19, 1, 5, 11, DType::bf16},
      {Kind::same3x3, 1, 5, 40, 3, 9, 5, DType::f16, false},
      {Kind::patch_tokens, 1, 5, 19, 2, 7, 9, DType::bf16},
      {Kind::patch_images, 1, 13, 40, 3, 6, 8, DType::bf16},
      {Kind::downsample, 1, 13, 7, 2, 9, 8, DType::bf16},
      {Kind::downsample, 1, 5, 3, 1, 7, 7, DType::f32, false},
      {Kind::causal, 1, 5, 19, 3, 7, 9, DType::bf16},
      {Kind::causal_cached, 2, 3, 3, 2, 5, 5, DType::f32},
      {Kind::causal_cached, 1, 13, 7, 1, 5, 7, DType::f16},
      {Kind::pointwise, 1, 13, 40, 3, 5, 7, DType::f32},
      {Kind::upsample_conv, 1, 5, 7, 3, 5, 7, DType::bf16, true, true},
      {Kind::upsample_conv, 1, 3, 19, 2, 3, 5, DType::bf16, true, true},
      {Kind::same3x3, 1, 37, 140, 1, 15, 17, DType::bf16},  // 255 pixels x 140 channels: partial tiles both ways
      {Kind::causal, 1, 13, 40, 2, 11, 13, DType::bf16},
      // Input channels a multiple of the reduction step (32 at the GPUs' and lavapipe's layouts, as the VAE's
      // 128..512): the tensor-core kernel's one-tap-per-step gather, with and without the fused upsampling.
      {Kind::same3x3, 1, 64, 19, 2, 7, 9, DType::bf16},
      {Kind::causal, 1, 32, 7, 3, 5, 7, DType::f16},
      {Kind::upsample_conv, 1, 32, 7, 2, 3, 5, DType::bf16, true, true},
      // The same with every other variant: the stride-2 downsample, the cache's frames, a 1x1 kernel (the 16-byte
      // gathers of DeviceTuning::conv_coopmat_vector_loads take all of them).
      {Kind::downsample, 1, 32, 19, 2, 9, 8, DType::bf16},
      {Kind::causal_cached, 1, 32, 7, 2, 5, 7, DType::bf16},
      {Kind::pointwise, 1, 64, 7, 3, 5, 7, DType::bf16},
  };
}

class ConvFamilies : public GpuTest {
 protected:
  // fp16_operands: the reference rounds x and w to fp16 as the tensor-core kernel and its twin do.
  void run_all(const std::string& overrides, bool twin, const std::vector<Case>& cases, bool fp16_operands = false) {
    ops::ScopedTuningOverride scope(overrides);
    struct Reset {
      ~Reset() { ops::set_conv_register_block({}); }
    } reset;
    ops::ConvRegisterBlock blk;
    blk.coopmat_twin = twin;
    ops::set_conv_register_block(blk);
    if (!twin && overrides.rfind("conv=coopmat", 0) == 0) {
      ASSERT_EQ(ops::device_tuning(ctx().caps()).conv, ops::KernelFamily::coopmat) << overrides;
    }
    uint32_t seed = 500;
    for (const Case& k : cases)
      check(ctx(), k, seed += 10, twin || fp16_operands, (twin ? "coopmat twin " : "") + overrides);
  }
};

TEST_F(ConvFamilies, TiledEveryVariant) {
  ops::ScopedTuningOverride scope("conv=tiled");
  EXPECT_EQ(ops::device_tuning(ctx().caps()).conv, ops::KernelFamily::tiled);
  run_all("conv=tiled", false, all_cases());
}

// Other workgroup tiles (specialisation constants): partial tiles, one and several loads per invocation.
TEST_F(ConvFamilies, TiledOtherTiles) {
  std::vector<Case> cases = {all_cases()[1], all_cases()[8], all_cases()[13]};
  for (const char* o : {"conv=tiled,conv_tile_m=32,conv_tile_n=128", "conv=tiled,conv_tile_m=128,conv_tile_n=32"}) run_all(o, false, cases);
}

// The coopmat kernel's tiles, loads, fp16 rounding and epilogue (its fp32 twin), against the reference
// on fp16-rounded operands.
TEST_F(ConvFamilies, CoopmatTwinEveryVariant) { run_all("", true, all_cases()); }

// The twin at other layouts (the tuning's coopmat_lanes and conv_coopmat): 8 lanes (32 fragment elements a lane,
// 64 invocations gathering 2 pixels each); 2 x 2 subgroups of 2 x 2 fragments (64 x 64, 2 invocations a pixel);
// 8 lanes on 1 x 1 subgroups of 2 x 2 fragments, K 16 (8 invocations gathering 4 pixels and 4 channels each).
// On lavapipe's 32 KiB the default layout (128 x 128 at 16x16x16) holds one operand stage, these two.
TEST_F(ConvFamilies, CoopmatTwinOtherLayouts) {
  std::vector<Case> cases = {all_cases()[1], all_cases()[8], all_cases()[13], all_cases()[14]};
  for (const char* o : {"coopmat_lanes=8", "conv_coopmat=2x2x2x2x32", "coopmat_lanes=8,conv_coopmat=1x1x2x2x16"})
    run_all(o, true, cases);
}

// The tensor-core kernel itself, where the device has tensor cores (lavapipe 26.1 in the tensor-core pass,
// GPUs), against the reference on fp16-rounded operands (the twin's bound): the tuning's layout, then the
// others above, then one operand stage instead of two (where two fit, as on lavapipe 26.1, they are the default).
TEST_F(ConvFamilies, CoopmatEveryVariant) {
  if (!ops::device_tuning(ctx().caps()).coopmat.defined()) GTEST_SKIP() << "no cooperative-matrix shape";
  run_all("conv=coopmat", false, all_cases(), true);
  EXPECT_EQ(ops::device_tuning(ctx().caps()).conv_unfit, "");
  std::vector<Case> cases = {all_cases()[1], all_cases()[8], all_cases()[13], all_cases()[14]};
  cases.push_back(all_cases()[15]);  // 64 input channels: whole-tap steps at K 32
  for (const char* o : {"conv=coopmat,conv_coopmat=2x2x2x2x32", "conv=coopmat,conv_coopmat=1x1x2x2x16",
                        "conv=coopmat,conv_coopmat_double_buffer=off"})
    run_all(o, false, cases, true);
}

// The coopmat2 kernel (nn/conv_coopmat2, DeviceTuning::conv_coopmat2) against the reference, where the device has
// VK_NV_cooperative_matrix2's workgroup scope and tensor addressing (the device script runs ConvFamilies.* there):
// fp16 weights (the ones it takes, as the VAE packs them), input channels multiples of its K, every stride-1 variant
// (3x3 with its padding read by clamping, causal with and without the cache, 1x1, the x2 upsampling read through
// block size 2), output patches and channels past their tiles' ends; frames of a multiple of 4 pixels, whose first
// outputs the tensor store can take (16-byte aligned). Elsewhere the KHR kernel runs the same calls.
TEST_F(ConvFamilies, Coopmat2EveryStrideOneVariant) {
  if (!ops::device_tuning(ctx().caps()).coopmat.defined()) GTEST_SKIP() << "no cooperative-matrix shape";
  const std::vector<Case> cases = {
      {Kind::same3x3, 1, 64, 19, 2, 7, 8, DType::f16},
      {Kind::same3x3, 1, 32, 140, 1, 15, 36, DType::f16},  // 2 channel tiles, 4 row tiles, 2 column tiles
      {Kind::causal, 2, 32, 7, 3, 5, 8, DType::f16},
      {Kind::causal_cached, 1, 64, 40, 2, 5, 8, DType::f16},
      {Kind::pointwise, 1, 64, 7, 3, 5, 8, DType::f16},
      {Kind::upsample_conv, 1, 32, 19, 2, 3, 5, DType::f16, true, true},
      {Kind::upsample_conv, 1, 64, 7, 3, 5, 4, DType::f16, true, false},
  };
  auto created = [&] {
    bool found = false;
    ctx().pipelines().for_each([&](const vk::Pipeline& pl) { found = found || pl.name == "nn/conv_coopmat2"; });
    return found;
  };
  run_all("conv=coopmat,conv_coopmat2=on", false, cases, true);
  if (!ops::linear_coopmat2_unfit(ctx().caps(), {128, 128, 32, 256}).empty()) {
    EXPECT_FALSE(created()) << "the coopmat2 conv kernel was made on a device without its features";
    GTEST_SKIP() << "no coopmat2 here (the KHR kernel ran the cases)";
  }
  EXPECT_TRUE(created());
}

// Without usable cooperative matrices a forced coopmat family falls back to tiled (same results, bit for bit).
TEST_F(ConvFamilies, CoopmatFallsBackWithoutTensorCores) {
  vk::Context& c = ctx();
  if (ops::device_tuning(c.caps()).coopmat.defined()) GTEST_SKIP() << "the device has tensor cores";
  Video x = random_video(1, 5, 2, 7, 9, 900);
  std::vector<float> wv;
  Tensor wt = Tensor::upload(c, stored({7, 5, 3, 3}, DType::bf16, 901, 0.2f, wv));
  Tensor xt = Tensor::upload(c, HostTensor::from_f32({1, 5, 2, 7, 9}, x.v));
  std::vector<float> got[2];
  int i = 0;
  for (const char* o : {"conv=coopmat", "conv=tiled"}) {
    ops::ScopedTuningOverride scope(o);
    EXPECT_EQ(ops::device_tuning(c.caps()).conv, ops::KernelFamily::tiled) << o;
    Tensor y = Tensor::empty(c, {1, 7, 2, 7, 9}, DType::f32);
    ops::run_now(c, [&](vk::Recorder& rec) { ops::conv2d(rec, xt, wt, nullptr, y, ops::Conv2dParams::same3x3()); });
    got[i++] = y.download(c).to_f32();
  }
  EXPECT_EQ(std::memcmp(got[0].data(), got[1].data(), got[0].size() * 4), 0);
}

}  // namespace
}  // namespace dvs
