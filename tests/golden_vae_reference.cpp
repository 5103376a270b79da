// The CogVideoX VAE on shapes the pack does not have (non-square, sizes that are not multiples of the
// spatial ratio, batch 2, frame counts that split into several batches), checked against a plain
// double-precision C++ re-statement of diffusers' AutoencoderKLCogVideoX written here from its source
// (frame batches with the conv cache, GroupNorm per batch, SpatialNorm3D's first-frame split, Downsample3D /
// Upsample3D time rules). Weights: the pack's vae/. Tolerances: those of the pack's vae cases.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "spec/model_folder.hpp"
#include "io/npy.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "pipeline/job_stages.hpp"
#include "support/gpu.hpp"
#include "support/precision_rule.hpp"

namespace fs = std::filesystem;
using dvs::HostTensor;
using dvs::Tensor;

namespace {

// A [B, C, F, H, W] array of doubles.
struct V {
  int64_t B = 0, C = 0, F = 0, H = 0, W = 0;
  std::vector<double> d;
  V() = default;
  V(int64_t b, int64_t c, int64_t f, int64_t h, int64_t w) : B(b), C(c), F(f), H(h), W(w), d(size_t(b * c * f * h * w)) {}
  double& at(int64_t b, int64_t c, int64_t f, int64_t h, int64_t w) { return d[size_t((((b * C + c) * F + f) * H + h) * W + w)]; }
  double at(int64_t b, int64_t c, int64_t f, int64_t h, int64_t w) const {
    return d[size_t((((b * C + c) * F + f) * H + h) * W + w)];
  }
};

V slice_time(const V& x, int64_t s, int64_t e) {
  V y(x.B, x.C, e - s, x.H, x.W);
  for (int64_t b = 0; b < x.B; ++b)
    for (int64_t c = 0; c < x.C; ++c)
      for (int64_t f = s; f < e; ++f)
        for (int64_t h = 0; h < x.H; ++h)
          for (int64_t w = 0; w < x.W; ++w) y.at(b, c, f - s, h, w) = x.at(b, c, f, h, w);
  return y;
}

V cat_time(const V& a, const V& x) {
  V y(x.B, x.C, a.F + x.F, x.H, x.W);
  for (int64_t b = 0; b < x.B; ++b)
    for (int64_t c = 0; c < x.C; ++c)
      for (int64_t f = 0; f < y.F; ++f)
        for (int64_t h = 0; h < x.H; ++h)
          for (int64_t w = 0; w < x.W; ++w) y.at(b, c, f, h, w) = f < a.F ? a.at(b, c, f, h, w) : x.at(b, c, f - a.F, h, w);
  return y;
}

// fp32 -> fp16 -> fp32, round to nearest even: the operand rounding of dvs's 16-bit convolution kernels (the
// tensor-core kernel and its fp32 twin stage both operands in fp16 and accumulate in fp32).
double fp16_rounded(double v) { return double(dvs::f16_to_f32(dvs::f32_to_f16(float(v)))); }

V fp16_rounded(const V& x) {
  V y = x;
  for (double& t : y.d) t = fp16_rounded(t);
  return y;
}

struct RefVae {
  dvs::WeightSet ws;
  dvs::models::VaeConfig cfg;
  // Every convolution's input and weights rounded to fp16 first (products and sums still in double): the 16-bit run
  // a result of dvs's 16-bit conv kernels is judged against (the precision rule, support/precision_rule.hpp).
  bool fp16_operands = false;
  std::map<std::string, std::vector<double>> cache_w;

  explicit RefVae(const fs::path& dir, bool fp16 = false)
      : ws(dvs::WeightSet::open_dir(dir)), cfg(dvs::models::VaeConfig::from_json([&] {
          std::ifstream f(dir / "config.json");
          return nlohmann::json::parse(f);
        }())),
        fp16_operands(fp16) {}

  const std::vector<double>& w(const std::string& name) {
    auto it = cache_w.find(name);
    if (it != cache_w.end()) return it->second;
    const auto f = ws.load(name).to_f32();
    return cache_w.emplace(name, std::vector<double>(f.begin(), f.end())).first->second;
  }

  // A convolution's weights as its kernel reads them (rounded to fp16 under fp16_operands).
  const std::vector<double>& conv_w(const std::string& name) {
    if (!fp16_operands) return w(name);
    const std::string key = name + " (fp16)";
    auto it = cache_w.find(key);
    if (it != cache_w.end()) return it->second;
    std::vector<double> r = w(name);
    for (double& t : r) t = fp16_rounded(t);
    return cache_w.emplace(key, std::move(r)).first->second;
  }

  // CogVideoXCausalConv3d: time prefix = cache or kt-1 copies of frame 0; cache' = last kt-1 padded frames.
  V causal_conv(const V& x, const std::string& p, std::map<std::string, V>* caches) {
    const HostTensor wt = ws.load(p + ".conv.weight");
    const auto& W = conv_w(p + ".conv.weight");
    const auto& bias = w(p + ".conv.bias");
    const int64_t co = wt.shape[0], ci = wt.shape[1], kt = wt.shape[2], kh = wt.shape[3], kw = wt.shape[4];
    V xp = x;
    if (kt > 1) {
      V prefix;
      if (caches && caches->count(p)) {
        prefix = caches->at(p);
      } else {
        V first = slice_time(x, 0, 1);
        prefix = first;
        for (int64_t i = 1; i < kt - 1; ++i) prefix = cat_time(prefix, first);
      }
      xp = cat_time(prefix, x);
      if (caches) (*caches)[p] = slice_time(xp, xp.F - (kt - 1), xp.F);
    }
    if (fp16_operands) xp = fp16_rounded(xp);
    const int64_t ph = (kh - 1) / 2, pw = (kw - 1) / 2;
    V y(x.B, co, xp.F - kt + 1, x.H, x.W);
    for (int64_t b = 0; b < y.B; ++b)
      for (int64_t o = 0; o < co; ++o)
        for (int64_t f = 0; f < y.F; ++f)
          for (int64_t h = 0; h < y.H; ++h)
            for (int64_t q = 0; q < y.W; ++q) {
              double s = bias[size_t(o)];
              for (int64_t c = 0; c < ci; ++c)
                for (int64_t a = 0; a < kt; ++a)
                  for (int64_t i = 0; i < kh; ++i)
                    for (int64_t j = 0; j < kw; ++j) {
                      const int64_t hh = h + i - ph, ww = q + j - pw;
                      if (hh < 0 || hh >= x.H || ww < 0 || ww >= x.W) continue;
                      s += W[size_t((((o * ci + c) * kt + a) * kh + i) * kw + j)] * xp.at(b, c, f + a, hh, ww);
                    }
              y.at(b, o, f, h, q) = s;
            }
    return y;
  }

  V conv1x1(const V& input, const std::string& wname, const std::string& bname) {
    const V x = fp16_operands ? fp16_rounded(input) : input;
    const HostTensor wt = ws.load(wname);
    const auto& W = conv_w(wname);
    const auto& bias = w(bname);
    const int64_t co = wt.shape[0], ci = wt.shape[1];
    V y(x.B, co, x.F, x.H, x.W);
    const int64_t S = x.F * x.H * x.W;
    for (int64_t b = 0; b < x.B; ++b)
      for (int64_t o = 0; o < co; ++o)
        for (int64_t s = 0; s < S; ++s) {
          double acc = bias[size_t(o)];
          for (int64_t c = 0; c < ci; ++c) acc += W[size_t(o * ci + c)] * x.d[size_t((b * ci + c) * S + s)];
          y.d[size_t((b * co + o) * S + s)] = acc;
        }
    return y;
  }

  V group_norm(const V& x, const std::string& p, double eps, bool silu) {
    const auto& g = w(p + ".weight");
    const auto& be = w(p + ".bias");
    const int64_t G = cfg.norm_num_groups, cg = x.C / G, S = x.F * x.H * x.W;
    V y = x;
    for (int64_t b = 0; b < x.B; ++b)
      for (int64_t k = 0; k < G; ++k) {
        const size_t base = size_t((b * x.C + k * cg) * S), n = size_t(cg * S);
        double m = 0, v = 0;
        for (size_t i = 0; i < n; ++i) m += x.d[base + i];
        m /= double(n);
        for (size_t i = 0; i < n; ++i) v += (x.d[base + i] - m) * (x.d[base + i] - m);
        v /= double(n);
        const double inv = 1.0 / std::sqrt(v + eps);
        for (size_t i = 0; i < n; ++i) {
          const int64_t c = k * cg + int64_t(i) / S;
          double t = (x.d[base + i] - m) * inv * g[size_t(c)] + be[size_t(c)];
          if (silu) t = t / (1.0 + std::exp(-t));
          y.d[base + i] = t;
        }
      }
    return y;
  }

  static V silu(V x) {
    for (double& t : x.d) t = t / (1.0 + std::exp(-t));
    return x;
  }

  // F.interpolate(mode="nearest") to (Fo, Ho, Wo): src = floor(dst * in / out).
  static V nearest(const V& x, int64_t fo, int64_t ho, int64_t wo) {
    V y(x.B, x.C, fo, ho, wo);
    auto src = [](int64_t d, int64_t in, int64_t out) {
      return std::min(in - 1, int64_t(std::floor(double(d) * double(in) / double(out))));
    };
    for (int64_t b = 0; b < x.B; ++b)
      for (int64_t c = 0; c < x.C; ++c)
        for (int64_t f = 0; f < fo; ++f)
          for (int64_t h = 0; h < ho; ++h)
            for (int64_t q = 0; q < wo; ++q)
              y.at(b, c, f, h, q) = x.at(b, c, src(f, x.F, fo), src(h, x.H, ho), src(q, x.W, wo));
    return y;
  }

  V spatial_norm(const V& f, const V& zq0, const std::string& p) {
    V zq;
    if (f.F > 1 && f.F % 2 == 1) {
      zq = cat_time(nearest(slice_time(zq0, 0, 1), 1, f.H, f.W), nearest(slice_time(zq0, 1, zq0.F), f.F - 1, f.H, f.W));
    } else {
      zq = nearest(zq0, f.F, f.H, f.W);
    }
    const V cy = conv1x1(zq, p + ".conv_y.conv.weight", p + ".conv_y.conv.bias");
    const V cb = conv1x1(zq, p + ".conv_b.conv.weight", p + ".conv_b.conv.bias");
    V n = group_norm(f, p + ".norm_layer", 1e-6, false);
    for (size_t i = 0; i < n.d.size(); ++i) n.d[i] = n.d[i] * cy.d[i] + cb.d[i];
    return n;
  }

  V resnet(const V& x, const std::string& p, const V* zq, std::map<std::string, V>& caches) {
    V h = zq ? silu(spatial_norm(x, *zq, p + ".norm1")) : group_norm(x, p + ".norm1", cfg.norm_eps, true);
    h = causal_conv(h, p + ".conv1", &caches);
    h = zq ? silu(spatial_norm(h, *zq, p + ".norm2")) : group_norm(h, p + ".norm2", cfg.norm_eps, true);
    h = causal_conv(h, p + ".conv2", &caches);
    V s = x.C != h.C ? conv1x1(x, p + ".conv_shortcut.weight", p + ".conv_shortcut.bias") : x;
    for (size_t i = 0; i < h.d.size(); ++i) h.d[i] += s.d[i];
    return h;
  }

  // Conv2d per frame, stride s, zero padding (top, bottom, left, right).
  V conv2d(const V& input, const std::string& p, int64_t s, int64_t pt, int64_t pb, int64_t pl, int64_t pr) {
    const V x = fp16_operands ? fp16_rounded(input) : input;
    const HostTensor wt = ws.load(p + ".weight");
    const auto& W = conv_w(p + ".weight");
    const auto& bias = w(p + ".bias");
    const int64_t co = wt.shape[0], ci = wt.shape[1], kh = wt.shape[2], kw = wt.shape[3];
    const int64_t ho = (x.H + pt + pb - kh) / s + 1, wo = (x.W + pl + pr - kw) / s + 1;
    V y(x.B, co, x.F, ho, wo);
    for (int64_t b = 0; b < x.B; ++b)
      for (int64_t o = 0; o < co; ++o)
        for (int64_t f = 0; f < x.F; ++f)
          for (int64_t h = 0; h < ho; ++h)
            for (int64_t q = 0; q < wo; ++q) {
              double acc = bias[size_t(o)];
              for (int64_t c = 0; c < ci; ++c)
                for (int64_t i = 0; i < kh; ++i)
                  for (int64_t j = 0; j < kw; ++j) {
                    const int64_t hh = h * s + i - pt, ww = q * s + j - pl;
                    if (hh < 0 || hh >= x.H || ww < 0 || ww >= x.W) continue;
                    acc += W[size_t(((o * ci + c) * kh + i) * kw + j)] * x.at(b, c, f, hh, ww);
                  }
              y.at(b, o, f, h, q) = acc;
            }
    return y;
  }

  V encoder(const V& x, std::map<std::string, V>& caches) {
    const size_t n = cfg.block_out_channels.size();
    V h = causal_conv(x, "encoder.conv_in", &caches);
    for (size_t i = 0; i < n; ++i) {
      const std::string p = "encoder.down_blocks." + std::to_string(i);
      for (int64_t j = 0; j < cfg.layers_per_block; ++j) h = resnet(h, p + ".resnets." + std::to_string(j), nullptr, caches);
      if (i + 1 < n) {
        if (int64_t(i) < cfg.temporal_levels()) {
          // Downsample3D compress_time: odd F keeps frame 0, pairs of the rest averaged.
          const int64_t keep = h.F % 2, fo = keep + (h.F - keep) / 2;
          V t(h.B, h.C, fo, h.H, h.W);
          for (int64_t b = 0; b < h.B; ++b)
            for (int64_t c = 0; c < h.C; ++c)
              for (int64_t f = 0; f < fo; ++f)
                for (int64_t y = 0; y < h.H; ++y)
                  for (int64_t q = 0; q < h.W; ++q)
                    t.at(b, c, f, y, q) = keep && f == 0 ? h.at(b, c, 0, y, q)
                                                         : 0.5 * (h.at(b, c, keep + 2 * (f - keep), y, q) +
                                                                  h.at(b, c, keep + 2 * (f - keep) + 1, y, q));
          h = t;
        }
        h = conv2d(h, p + ".downsamplers.0.conv", 2, 0, 1, 0, 1);
      }
    }
    for (int j = 0; j < 2; ++j) h = resnet(h, "encoder.mid_block.resnets." + std::to_string(j), nullptr, caches);
    h = group_norm(h, "encoder.norm_out", 1e-6, true);
    return causal_conv(h, "encoder.conv_out", &caches);
  }

  V decoder(const V& z, std::map<std::string, V>& caches) {
    const size_t n = cfg.block_out_channels.size();
    V h = causal_conv(z, "decoder.conv_in", &caches);
    for (int j = 0; j < 2; ++j) h = resnet(h, "decoder.mid_block.resnets." + std::to_string(j), &z, caches);
    for (size_t i = 0; i < n; ++i) {
      const std::string p = "decoder.up_blocks." + std::to_string(i);
      for (int64_t j = 0; j <= cfg.layers_per_block; ++j) h = resnet(h, p + ".resnets." + std::to_string(j), &z, caches);
      if (i + 1 < n) {
        const bool ct = int64_t(i) < cfg.temporal_levels();
        if (ct && h.F > 1 && h.F % 2 == 1)
          h = cat_time(nearest(slice_time(h, 0, 1), 1, 2 * h.H, 2 * h.W), nearest(slice_time(h, 1, h.F), 2 * (h.F - 1), 2 * h.H, 2 * h.W));
        else if (ct && h.F > 1)
          h = nearest(h, 2 * h.F, 2 * h.H, 2 * h.W);
        else
          h = nearest(h, h.F, 2 * h.H, 2 * h.W);
        h = conv2d(h, p + ".upsamplers.0.conv", 1, 1, 1, 1, 1);
      }
    }
    h = silu(spatial_norm(h, z, "decoder.norm_out"));
    return causal_conv(h, "decoder.conv_out", &caches);
  }

  // diffusers' _encode / _decode frame batching: [0, b + r), then b at a time (r = F mod b).
  static std::vector<std::pair<int64_t, int64_t>> batches(int64_t frames, int64_t b) {
    std::vector<std::pair<int64_t, int64_t>> out;
    const int64_t n = std::max<int64_t>(frames / b, 1), r = frames % b;
    for (int64_t i = 0; i < n; ++i) out.emplace_back(b * i + (i ? r : 0), std::min(frames, b * (i + 1) + r));
    return out;
  }

  V encode_moments(const V& x) {
    std::map<std::string, V> caches;
    V out;
    bool first = true;
    for (auto [s, e] : batches(x.F, 8)) {
      V m = encoder(slice_time(x, s, e), caches);
      out = first ? m : cat_time(out, m);
      first = false;
    }
    return out;
  }

  V decode(const V& z) {
    std::map<std::string, V> caches;
    V out;
    bool first = true;
    for (auto [s, e] : batches(z.F, 2)) {
      V m = decoder(slice_time(z, s, e), caches);
      out = first ? m : cat_time(out, m);
      first = false;
    }
    return out;
  }
};

V random_v(int64_t b, int64_t c, int64_t f, int64_t h, int64_t w, uint32_t seed) {
  V x(b, c, f, h, w);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (double& t : x.d) t = double(float(u(rng)));  // representable in f32
  return x;
}

HostTensor to_host(const V& x) {
  std::vector<float> f(x.d.begin(), x.d.end());
  return HostTensor::from_f32({x.B, x.C, x.F, x.H, x.W}, f);
}

// Whether this test's convolutions ran a 16-bit-operand kernel (support/precision_rule.hpp): its results are then
// judged by the precision rule against this reference's fp16-operand run, computed only then.
bool convs_ran_16bit() {
  return !dvs::test::sixteen_bit_ops_run(dvs::test::kernels_run_in_test(), dvs::test::kConvOps).empty();
}

// dvs's result against the double reference `want`: within the case's tolerance, or (16-bit conv kernels) by the
// precision rule with `want16`, the same reference with fp16 conv operands, as the 16-bit run.
void expect_close(const std::string& what, const HostTensor& got, const V& want, const V* want16, double atol,
                  double rtol) {
  ASSERT_EQ(got.shape, (dvs::Shape{want.B, want.C, want.F, want.H, want.W})) << what;
  std::optional<std::vector<float>> run16;
  if (want16) run16.emplace(want16->d.begin(), want16->d.end());
  const auto v = dvs::test::judge_golden(
      what, got.to_f32(), std::vector<float>(want.d.begin(), want.d.end()), run16,
      "made only when a conv ran with 16-bit operands", atol, rtol,
      dvs::test::sixteen_bit_ops_run(dvs::test::kernels_run_in_test(), dvs::test::kConvOps), "fp16-operand reference");
  std::printf("%s\n", v.report.c_str());
  EXPECT_TRUE(v.pass) << v.report;
}

class VaeReference : public dvs::test::GpuTest {
 protected:
  fs::path vae_dir() { return fs::path(dvs::test::golden_dir()) / "model" / "vae"; }
};

// Encode then decode one clip against the reference (decode of the reference mean, so the decoder is judged
// on its own). Encode tolerance 5e-5 / 1e-4 and decode 5e-4 / 1e-4, as the pack's vae cases.
void check_clip(dvs::vk::Context& ctx, const fs::path& dir, int64_t B, int64_t F, int64_t H, int64_t W, uint32_t seed) {
  RefVae ref(dir), ref16(dir, /*fp16=*/true);
  dvs::models::CogVideoXVae vae(ctx, dir);
  const std::string tag = std::to_string(B) + "x" + std::to_string(F) + "x" + std::to_string(H) + "x" + std::to_string(W);
  const V video = random_v(B, ref.cfg.in_channels, F, H, W, seed);
  const auto post = vae.encode(Tensor::upload(ctx, to_host(video)));
  const bool sixteen = convs_ran_16bit();
  const V moments = ref.encode_moments(video), moments16 = sixteen ? ref16.encode_moments(video) : V();
  expect_close("ref encode moments " + tag, post.moments.download(ctx), moments, sixteen ? &moments16 : nullptr, 5e-5,
               1e-4);
  auto mean_of = [](const V& m) {  // each sample's first half of the moments
    V mean(m.B, m.C / 2, m.F, m.H, m.W);
    const size_t n = mean.d.size() / size_t(std::max<int64_t>(mean.B, 1));
    for (int64_t b = 0; b < mean.B; ++b)
      std::copy_n(m.d.begin() + ptrdiff_t(size_t(b) * 2 * n), n, mean.d.begin() + ptrdiff_t(size_t(b) * n));
    return mean;
  };
  const V mean = mean_of(moments), mean16 = sixteen ? mean_of(moments16) : V();
  expect_close("ref encode mean " + tag, post.mean.download(ctx), mean, sixteen ? &mean16 : nullptr, 5e-5, 1e-4);
  V mean_f32 = mean;
  for (double& t : mean_f32.d) t = double(float(t));
  const HostTensor decoded = vae.decode(Tensor::upload(ctx, to_host(mean_f32))).download(ctx);
  const V frames = ref.decode(mean_f32), frames16 = convs_ran_16bit() ? ref16.decode(mean_f32) : V();
  expect_close("ref decode " + tag, decoded, frames, convs_ran_16bit() ? &frames16 : nullptr, 5e-4, 1e-4);
}

}  // namespace

// Non-square, W not a multiple of 8 (20 -> 10 -> 5 -> 3 latent columns), 17 frames: two encode batches
// ([0:9], [9:17]) and two decode batches ([0:3], [3:5]).
TEST_F(VaeReference, NonSquare17Frames) { check_clip(ctx(), vae_dir(), 1, 17, 16, 20, 7); }

// Batch 2 (GroupNorm statistics per sample), a single frame (image encode, F = 1 through every time rule).
TEST_F(VaeReference, Batch2SingleFrame) { check_clip(ctx(), vae_dir(), 2, 1, 24, 16, 11); }

// Batch 2 through two frame batches (the conv cache holds both samples).
TEST_F(VaeReference, Batch2TwoFrameBatches) { check_clip(ctx(), vae_dir(), 2, 17, 8, 16, 3); }

// 24 frames: even batches [0:8],[8:16],[16:24] (no odd first frame); 6 latent frames decode as [0:2],[2:4],[4:6].
TEST_F(VaeReference, EvenFrames) { check_clip(ctx(), vae_dir(), 1, 24, 8, 8, 5); }

// Which decoded frames dvs keeps for an even latent count, checked by value. diffusers decodes an even Fl as
// [0:2], [2:4], ...; a batch being even, its time upsampling (nearest, twice) repeats latent frame 0 four times
// like every other frame instead of keeping it apart, so 4·Fl frames come out for a 4·Fl − 3 frame video, frames
// 0..3 at latent 0's position and 4·k..4·k+3 at latent k's. The video's frames are latent 0's one frame, then four
// per later latent: the last 4·Fl − 3. decode_latent (what `dvs run` writes) must return exactly the reference's
// frames 3.. (clamped); keeping the first 4·Fl − 3 instead shifts every frame after 0 by three and fails here.
// (The reference here is the plain-C++ restatement of diffusers' decode; VaeGolden.EvenLatentCountDecode checks the
// same choice against diffusers' own decode of even-count latents, case vae_decode_even_latent.)
TEST_F(VaeReference, EvenLatentCountKeepsTheLastFourFlMinusThreeFrames) {
  RefVae ref(vae_dir());
  dvs::models::CogVideoXVae vae(ctx(), vae_dir());
  const int64_t Fl = 4, C = ref.cfg.latent_channels, h = 3, w = 5;  // odd latent sizes: 24 x 40 frames
  const float scaling = float(vae.config().scaling_factor);
  const int64_t frames = 4 * Fl - 3;
  // The diffusion-space latent [Fl, C, h, w] and the reference's [1, C, Fl, h, w] in VAE units (as to_vae_layout
  // scales it: one f32 multiply by 1/scaling).
  const V z = random_v(1, C, Fl, h, w, 21);
  HostTensor diffusion({Fl, C, h, w}, dvs::DType::f32);
  V vae_space = z;
  for (int64_t f = 0; f < Fl; ++f)
    for (int64_t c = 0; c < C; ++c)
      for (int64_t y = 0; y < h; ++y)
        for (int64_t x = 0; x < w; ++x) {
          const float v = float(z.at(0, c, f, y, x)) * scaling;
          diffusion.as<float>()[((f * C + c) * h + y) * w + x] = v;
          vae_space.at(0, c, f, y, x) = double(v * (1.0f / scaling));
        }
  const V all = ref.decode(vae_space);
  ASSERT_EQ(all.F, 4 * Fl) << "the reference decodes an even latent count to 4·Fl frames";

  dvs::RunOptions o;  // untiled decode
  const HostTensor got = dvs::decode_latent(ctx(), vae, o, Tensor::upload(ctx(), diffusion), scaling, int(frames));
  ASSERT_EQ(got.shape, (dvs::Shape{frames, 3, all.H, all.W}));
  auto kept = [&](const V& decoded) {  // the reference's frames 3.., clamped
    V k(1, 3, frames, decoded.H, decoded.W);
    for (int64_t f = 0; f < frames; ++f)
      for (int64_t c = 0; c < 3; ++c)
        for (int64_t y = 0; y < k.H; ++y)
          for (int64_t x = 0; x < k.W; ++x) k.at(0, c, f, y, x) = std::clamp(decoded.at(0, c, f + 3, y, x), -1.0, 1.0);
    return k;
  };
  const V want = kept(all);
  const bool sixteen = convs_ran_16bit();
  const V want16 = sixteen ? kept(RefVae(vae_dir(), /*fp16=*/true).decode(vae_space)) : V();
  // decode_latent's [F, 3, H, W] as the reference's [1, 3, F, H, W].
  HostTensor got_cf({1, 3, frames, want.H, want.W}, dvs::DType::f32);
  const int64_t plane = want.H * want.W;
  for (int64_t f = 0; f < frames; ++f)
    for (int64_t c = 0; c < 3; ++c)
      std::copy_n(got.as<float>() + (f * 3 + c) * plane, plane, got_cf.as<float>() + (c * frames + f) * plane);
  expect_close("even Fl decode, kept frames", got_cf, want, sixteen ? &want16 : nullptr, 5e-4, 1e-4);
  // The test can tell the two choices apart: the reference's first 4·Fl − 3 frames are not its last.
  double shift = 0;
  for (int64_t c = 0; c < 3; ++c)
    for (int64_t y = 0; y < want.H; ++y)
      for (int64_t x = 0; x < want.W; ++x)
        shift = std::max(shift, std::fabs(std::clamp(all.at(0, c, 1, y, x), -1.0, 1.0) - want.at(0, c, 1, y, x)));
  EXPECT_GT(shift, 1e-2) << "frame 1 of 'keep the first' must differ from frame 1 of 'keep the last'";
}

// The reference itself reproduces the pack's vae_frame_batching case (so agreement with it means something).
TEST(VaeReferenceSelfCheck, MatchesPackFrameBatching) {
  const fs::path pack(dvs::test::golden_dir());
  RefVae ref(pack / "model" / "vae");
  auto from_host = [](const HostTensor& h) {
    V x(h.shape[0], h.shape[1], h.shape[2], h.shape[3], h.shape[4]);
    const auto f = h.to_f32();
    std::copy(f.begin(), f.end(), x.d.begin());
    return x;
  };
  const V moments = ref.encode_moments(from_host(dvs::read_npy(pack / "vae/chunk17_video.npy")));
  const HostTensor mean = dvs::read_npy(pack / "vae/chunk17_encode_mean.npy");
  const auto m = mean.to_f32();
  double err = 0;
  const size_t n = m.size();  // batch 1: the first half of the moments is the mean
  for (size_t i = 0; i < n; ++i) err = std::max(err, std::fabs(moments.d[i] - double(m[i])));
  std::printf("[ golden ] reference vs pack chunk17 mean: max |err| = %.3g\n", err);
  EXPECT_LT(err, 5e-5);
  const V frames = ref.decode(from_host(mean));
  const auto g = dvs::read_npy(pack / "vae/chunk17_decode_frames.npy").to_f32();
  err = 0;
  for (size_t i = 0; i < g.size(); ++i) err = std::max(err, std::fabs(frames.d[i] - double(g[i])));
  std::printf("[ golden ] reference vs pack chunk17 decode: max |err| = %.3g\n", err);
  EXPECT_LT(err, 5e-4);
}
