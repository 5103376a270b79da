#include "realsize_reference.hpp"

#include <algorithm>
#include <cmath>
#include <string>

#include "dvs/error.hpp"

#ifdef DVS_HAVE_BLAS
#include <cblas.h>
#endif

namespace dvs::bench::realsize {
namespace {

using Vec = std::vector<float>;

// y[M, N] (+)= x[M, K] · w[N, K]ᵀ, as torch's Linear.
void gemm_nt(const float* x, int64_t M, int64_t K, const float* w, int64_t N, float* y, bool accumulate = false) {
#ifdef DVS_HAVE_BLAS
  cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasTrans, int(M), int(N), int(K), 1.0f, x, int(K), w, int(K),
              accumulate ? 1.0f : 0.0f, y, int(N));
#else
  (void)x, (void)M, (void)K, (void)w, (void)N, (void)y, (void)accumulate;
  throw Error("dvs-bench realsize: the CPU references need OpenBLAS (build with BLAS found)");
#endif
}

Vec linear(const float* x, int64_t M, int64_t K, HostWeights& w, const std::string& name) {
  const Vec& wt = w[name + ".weight"];
  const int64_t N = int64_t(wt.size()) / K;
  Vec y(static_cast<size_t>(M * N));
  gemm_nt(x, M, K, wt.data(), N, y.data());
  if (w.has(name + ".bias")) {
    const Vec& b = w[name + ".bias"];
    for (int64_t m = 0; m < M; ++m)
      for (int64_t n = 0; n < N; ++n) y[size_t(m * N + n)] += b[size_t(n)];
  }
  return y;
}
Vec linear(const Vec& x, int64_t K, HostWeights& w, const std::string& name) {
  return linear(x.data(), int64_t(x.size()) / K, K, w, name);
}

float silu(float x) { return x / (1.0f + std::exp(-x)); }
float gelu_tanh(float x) {
  return 0.5f * x * (1.0f + std::tanh(0.7978845608028654f * (x + 0.044715f * x * x * x)));
}

// LayerNorm of one row (weight / bias may be null).
void layernorm_row(const float* x, float* y, int64_t n, float eps, const float* wt, const float* b) {
  double mean = 0, var = 0;
  for (int64_t i = 0; i < n; ++i) mean += x[i];
  mean /= double(n);
  for (int64_t i = 0; i < n; ++i) var += (x[i] - mean) * (x[i] - mean);
  const double inv = 1.0 / std::sqrt(var / double(n) + eps);
  for (int64_t i = 0; i < n; ++i) {
    float v = float((x[i] - mean) * inv);
    if (wt) v = v * wt[i] + (b ? b[i] : 0.0f);
    y[i] = v;
  }
}

// T5LayerNorm: x / sqrt(mean(x²) + eps) · w, no mean removal, no bias.
Vec rmsnorm(const Vec& x, int64_t d, const Vec& wt, float eps) {
  Vec y(x.size());
  for (size_t r = 0; r < x.size() / size_t(d); ++r) {
    double ss = 0;
    for (int64_t i = 0; i < d; ++i) ss += double(x[r * d + i]) * x[r * d + i];
    const double inv = 1.0 / std::sqrt(ss / double(d) + eps);
    for (int64_t i = 0; i < d; ++i) y[r * d + i] = float(x[r * d + i] * inv) * wt[size_t(i)];
  }
  return y;
}

// transformers T5Attention._relative_position_bucket, bidirectional; rel = key - query.
int64_t t5_bucket(int64_t rel, int64_t buckets, int64_t max_distance) {
  buckets /= 2;
  int64_t ret = rel > 0 ? buckets : 0;
  const int64_t n = std::abs(rel), max_exact = buckets / 2;
  if (n < max_exact) return ret + n;
  const float f = std::log(float(n) / float(max_exact)) / std::log(float(max_distance) / float(max_exact)) *
                  float(buckets - max_exact);
  return ret + std::min<int64_t>(max_exact + int64_t(f), buckets - 1);
}

void softmax_inplace(float* s, int64_t n) {
  float mx = s[0];
  for (int64_t j = 1; j < n; ++j) mx = std::max(mx, s[j]);
  double sum = 0;
  for (int64_t j = 0; j < n; ++j) sum += (s[j] = std::exp(s[j] - mx));
  for (int64_t j = 0; j < n; ++j) s[j] = float(s[j] / sum);
}

}  // namespace

std::vector<float> t5_reference(HostWeights& w, const nlohmann::json& cfg, const std::vector<std::vector<int32_t>>& ids) {
  const int64_t d = cfg["d_model"], H = cfg["num_heads"], dk = cfg["d_kv"], I = H * dk, layers = cfg["num_layers"];
  const int64_t buckets = cfg["relative_attention_num_buckets"], maxd = cfg["relative_attention_max_distance"];
  const float eps = cfg["layer_norm_epsilon"].get<float>();
  const int64_t B = int64_t(ids.size()), L = int64_t(ids[0].size()), R = B * L;
  const Vec& emb = w["shared.weight"];
  Vec h(static_cast<size_t>(R * d));
  for (int64_t r = 0; r < R; ++r)
    std::copy_n(emb.begin() + ids[size_t(r / L)][size_t(r % L)] * d, d, h.begin() + r * d);
  const Vec& rab = w["encoder.block.0.layer.0.SelfAttention.relative_attention_bias.weight"];  // [buckets, H]
  for (int64_t li = 0; li < layers; ++li) {
    const std::string p = "encoder.block." + std::to_string(li) + ".layer.";
    const Vec x = rmsnorm(h, d, w[p + "0.layer_norm.weight"], eps);
    const Vec q = linear(x, d, w, p + "0.SelfAttention.q"), k = linear(x, d, w, p + "0.SelfAttention.k"),
              v = linear(x, d, w, p + "0.SelfAttention.v");
    Vec att(static_cast<size_t>(R * I), 0.0f), s(static_cast<size_t>(L));
    for (int64_t b = 0; b < B; ++b)
      for (int64_t hd = 0; hd < H; ++hd)
        for (int64_t i = 0; i < L; ++i) {
          const float* qi = &q[size_t((b * L + i) * I + hd * dk)];
          for (int64_t j = 0; j < L; ++j) {  // T5: unscaled logits + relative position bias
            const float* kj = &k[size_t((b * L + j) * I + hd * dk)];
            float acc = 0;
            for (int64_t e = 0; e < dk; ++e) acc += qi[e] * kj[e];
            s[size_t(j)] = acc + rab[size_t(t5_bucket(j - i, buckets, maxd) * H + hd)];
          }
          softmax_inplace(s.data(), L);
          float* o = &att[size_t((b * L + i) * I + hd * dk)];
          for (int64_t j = 0; j < L; ++j)
            for (int64_t e = 0; e < dk; ++e) o[e] += s[size_t(j)] * v[size_t((b * L + j) * I + hd * dk + e)];
        }
    const Vec o = linear(att, I, w, p + "0.SelfAttention.o");
    for (size_t i = 0; i < h.size(); ++i) h[i] += o[i];
    const Vec x2 = rmsnorm(h, d, w[p + "1.layer_norm.weight"], eps);
    Vec g = linear(x2, d, w, p + "1.DenseReluDense.wi_0");
    const Vec u = linear(x2, d, w, p + "1.DenseReluDense.wi_1");
    for (size_t i = 0; i < g.size(); ++i) g[i] = gelu_tanh(g[i]) * u[i];
    const Vec f = linear(g, int64_t(g.size()) / R, w, p + "1.DenseReluDense.wo");
    for (size_t i = 0; i < h.size(); ++i) h[i] += f[i];
  }
  return rmsnorm(h, d, w["encoder.final_layer_norm.weight"], eps);
}

std::vector<std::vector<float>> transformer_reference(HostWeights& w, const nlohmann::json& cfg, const std::vector<float>& latent,
                                                      const Shape& ls, const std::vector<float>& text, int64_t L,
                                                      const std::vector<float>& timesteps, const std::vector<float>& cos,
                                                      const std::vector<float>& sin,
                                                      const std::vector<TokenSample>& samples) {
  const int64_t nh = cfg["num_attention_heads"], Dh = cfg["attention_head_dim"], D = nh * Dh;
  const int64_t p = cfg["patch_size"], Tdim = cfg["text_embed_dim"];
  const float eps = cfg["norm_eps"].get<float>();
  const bool flip = cfg["flip_sin_to_cos"].get<bool>();
  const double shift = cfg["freq_shift"].get<double>();
  if (cfg["num_layers"].get<int64_t>() != 1) throw Error("transformer_reference: one block only");
  const int64_t B = ls[0], F = ls[1], C = ls[2], Hh = ls[3], Ww = ls[4], Hp = Hh / p, Wp = Ww / p;
  const int64_t N = F * Hp * Wp, S = L + N, Cpp = C * p * p;
  const std::string blk = "transformer_blocks.0.";
  auto col = [](const Vec& v, int64_t off) { return v.data() + off; };
  std::vector<std::vector<float>> result(samples.size());
  for (int64_t b = 0; b < B; ++b) {
    // Timestep embedding (diffusers get_timestep_embedding) and the modulation vectors.
    Vec tproj(static_cast<size_t>(D));
    const int64_t half = D / 2;
    for (int64_t i = 0; i < half; ++i) {  // [sin | cos], flip_sin_to_cos: [cos | sin]
      const double arg = double(timesteps[size_t(b)]) * std::exp(-std::log(10000.0) * double(i) / (double(half) - shift));
      tproj[size_t(flip ? i : i + half)] = float(std::cos(arg));
      tproj[size_t(flip ? i + half : i)] = float(std::sin(arg));
    }
    Vec t1 = linear(tproj, D, w, "time_embedding.linear_1");
    for (float& v : t1) v = silu(v);
    Vec emb = linear(t1, int64_t(t1.size()), w, "time_embedding.linear_2");
    for (float& v : emb) v = silu(v);
    const int64_t T = int64_t(emb.size());
    const Vec mod1 = linear(emb, T, w, blk + "norm1.linear"), mod2 = linear(emb, T, w, blk + "norm2.linear");
    const Vec mod_out = linear(emb, T, w, "norm_out.linear");

    // Sequence: [text_proj(text); patch conv(latent)] + learned positional table.
    Vec h(static_cast<size_t>(S * D));
    {
      const Vec tp = linear(&text[size_t(b * L * Tdim)], L, Tdim, w, "patch_embed.text_proj");
      std::copy(tp.begin(), tp.end(), h.begin());
      Vec patches(static_cast<size_t>(N * Cpp));
      for (int64_t f = 0; f < F; ++f)
        for (int64_t y = 0; y < Hp; ++y)
          for (int64_t x = 0; x < Wp; ++x)
            for (int64_t c = 0; c < C; ++c)
              for (int64_t ky = 0; ky < p; ++ky)
                for (int64_t kx = 0; kx < p; ++kx)
                  patches[size_t(((f * Hp + y) * Wp + x) * Cpp + (c * p + ky) * p + kx)] =
                      latent[size_t((((b * F + f) * C + c) * Hh + y * p + ky) * Ww + x * p + kx)];
      const Vec pe = linear(patches, Cpp, w, "patch_embed.proj");
      std::copy(pe.begin(), pe.end(), h.begin() + L * D);
      const Vec& pos = w["patch_embed.pos_embedding"];
      for (size_t i = 0; i < h.size(); ++i) h[i] += pos[i];
    }
    // adaLN of row r into out with table `mod`: text rows use (enc_shift, enc_scale), video rows (shift, scale).
    auto adaln = [&](const float* x, float* out, int64_t r, const std::string& norm, const Vec& mod) {
      layernorm_row(x, out, D, eps, w[norm + ".weight"].data(), w[norm + ".bias"].data());
      const int64_t sh = r < L ? 3 * D : 0, sc = r < L ? 4 * D : D;
      for (int64_t i = 0; i < D; ++i) out[i] = out[i] * (1.0f + mod[size_t(sc + i)]) + mod[size_t(sh + i)];
    };
    auto head_norm_rope = [&](float* v, int64_t r, const std::string& norm) {
      for (int64_t hd = 0; hd < nh; ++hd) {
        float* x = v + hd * Dh;
        layernorm_row(x, x, Dh, 1e-6f, w[norm + ".weight"].data(), w[norm + ".bias"].data());
        if (r < L) continue;
        const float* c = col(cos, (r - L) * Dh);
        const float* s = col(sin, (r - L) * Dh);
        for (int64_t i = 0; i < Dh; i += 2) {  // diffusers apply_rotary_emb, pairs (2i, 2i+1)
          const float re = x[i], im = x[i + 1];
          x[i] = re * c[i] - im * s[i];
          x[i + 1] = im * c[i + 1] + re * s[i + 1];
        }
      }
    };
    Vec n1(static_cast<size_t>(S * D));
    for (int64_t r = 0; r < S; ++r) adaln(&h[size_t(r * D)], &n1[size_t(r * D)], r, blk + "norm1.norm", mod1);
    Vec k = linear(n1, D, w, blk + "attn1.to_k");
    const Vec v = linear(n1, D, w, blk + "attn1.to_v");
    for (int64_t r = 0; r < S; ++r) head_norm_rope(&k[size_t(r * D)], r, blk + "attn1.norm_k");
    for (size_t si = 0; si < samples.size(); ++si) {
      if (samples[si].b != b) continue;
      const int64_t r = L + samples[si].n;
      Vec q = linear(&n1[size_t(r * D)], 1, D, w, blk + "attn1.to_q");
      head_norm_rope(q.data(), r, blk + "attn1.norm_q");
      Vec att(static_cast<size_t>(D), 0.0f), s(static_cast<size_t>(S));
      const float scale = float(1.0 / std::sqrt(double(Dh)));
      for (int64_t hd = 0; hd < nh; ++hd) {
        for (int64_t j = 0; j < S; ++j) {
          float acc = 0;
          for (int64_t e = 0; e < Dh; ++e) acc += q[size_t(hd * Dh + e)] * k[size_t(j * D + hd * Dh + e)];
          s[size_t(j)] = acc * scale;
        }
        softmax_inplace(s.data(), S);
        for (int64_t j = 0; j < S; ++j)
          for (int64_t e = 0; e < Dh; ++e) att[size_t(hd * Dh + e)] += s[size_t(j)] * v[size_t(j * D + hd * Dh + e)];
      }
      Vec x(h.begin() + r * D, h.begin() + (r + 1) * D);
      const Vec o = linear(att, D, w, blk + "attn1.to_out.0");
      for (int64_t i = 0; i < D; ++i) x[size_t(i)] += mod1[size_t(2 * D + i)] * o[size_t(i)];  // video gate
      Vec n2(static_cast<size_t>(D));
      adaln(x.data(), n2.data(), r, blk + "norm2.norm", mod2);
      Vec ff = linear(n2, D, w, blk + "ff.net.0.proj");
      for (float& e : ff) e = gelu_tanh(e);
      const Vec f2 = linear(ff, int64_t(ff.size()), w, blk + "ff.net.2");
      for (int64_t i = 0; i < D; ++i) x[size_t(i)] += mod2[size_t(2 * D + i)] * f2[size_t(i)];
      // norm_final, then norm_out (AdaLayerNorm: shift, scale = chunk(2)), proj_out.
      layernorm_row(x.data(), x.data(), D, eps, w["norm_final.weight"].data(), w["norm_final.bias"].data());
      layernorm_row(x.data(), x.data(), D, eps, w["norm_out.norm.weight"].data(), w["norm_out.norm.bias"].data());
      for (int64_t i = 0; i < D; ++i) x[size_t(i)] = x[size_t(i)] * (1.0f + mod_out[size_t(D + i)]) + mod_out[size_t(i)];
      result[si] = linear(x, D, w, "proj_out");  // (c, ky, kx) order: diffusers' unpatchify
    }
  }
  return result;
}

// ---- VAE, one frame --------------------------------------------------------------------------------------------
namespace {

struct Img {
  int64_t C = 0, H = 0, W = 0;
  Vec d;
  Img() = default;
  Img(int64_t c, int64_t h, int64_t w) : C(c), H(h), W(w), d(size_t(c * h * w), 0.0f) {}
  float* plane(int64_t c) { return d.data() + c * H * W; }
  const float* plane(int64_t c) const { return d.data() + c * H * W; }
};

// Conv with a k x k spatial kernel (a causal 3-D kernel [O, I, kt, k, k] is summed over kt: on one frame with the
// first frame replicated as the causal padding, every time tap sees the same frame), zero padding lo/hi,
// stride s. im2col in bands of output rows + sgemm.
Img conv(const Img& x, HostWeights& w, const std::string& name, int64_t k, int64_t s, int64_t lo, int64_t hi) {
  const Vec& wt = w[name + ".weight"];  // [O, I, kt, k, k] or [O, I, k, k]
  const Vec& bias = w[name + ".bias"];
  const int64_t K = x.C * k * k, Oc = int64_t(bias.size()), taps = int64_t(wt.size()) / (Oc * K);
  Vec w2(static_cast<size_t>(Oc * K), 0.0f);
  for (int64_t o = 0; o < Oc; ++o)
    for (int64_t i = 0; i < x.C; ++i)
      for (int64_t t = 0; t < taps; ++t)
        for (int64_t e = 0; e < k * k; ++e)
          w2[size_t((o * x.C + i) * k * k + e)] += wt[size_t(((o * x.C + i) * taps + t) * k * k + e)];
  const int64_t Ho = (x.H + lo + hi - k) / s + 1, Wo = (x.W + lo + hi - k) / s + 1;
  Img y(Oc, Ho, Wo);
  const int64_t band = std::max<int64_t>(1, (int64_t(64) << 20) / std::max<int64_t>(1, K * Wo));
  Vec cols, out;
  for (int64_t r0 = 0; r0 < Ho; r0 += band) {
    const int64_t rows = std::min(band, Ho - r0), P = rows * Wo;
    cols.assign(size_t(K * P), 0.0f);
    for (int64_t i = 0; i < x.C; ++i)
      for (int64_t ky = 0; ky < k; ++ky)
        for (int64_t kx = 0; kx < k; ++kx) {
          float* c = &cols[size_t(((i * k + ky) * k + kx) * P)];
          for (int64_t r = 0; r < rows; ++r) {
            const int64_t iy = (r0 + r) * s + ky - lo;
            if (iy < 0 || iy >= x.H) continue;
            const float* src = x.plane(i) + iy * x.W;
            for (int64_t xo = 0; xo < Wo; ++xo) {
              const int64_t ix = xo * s + kx - lo;
              if (ix >= 0 && ix < x.W) c[r * Wo + xo] = src[ix];
            }
          }
        }
    out.assign(size_t(Oc * P), 0.0f);
#ifdef DVS_HAVE_BLAS
    cblas_sgemm(CblasRowMajor, CblasNoTrans, CblasNoTrans, int(Oc), int(P), int(K), 1.0f, w2.data(), int(K),
                cols.data(), int(P), 0.0f, out.data(), int(P));
#else
    throw Error("dvs-bench realsize: the CPU references need OpenBLAS");
#endif
    for (int64_t o = 0; o < Oc; ++o)
      for (int64_t e = 0; e < P; ++e) y.plane(o)[r0 * Wo + e] = out[size_t(o * P + e)] + bias[size_t(o)];
  }
  return y;
}

Img group_norm(const Img& x, HostWeights& w, const std::string& name, int64_t groups, float eps) {
  const Vec& g = w[name + ".weight"];
  const Vec& b = w[name + ".bias"];
  Img y(x.C, x.H, x.W);
  const int64_t cg = x.C / groups, n = cg * x.H * x.W;
  for (int64_t gi = 0; gi < groups; ++gi) {
    const float* src = x.plane(gi * cg);
    double mean = 0, var = 0;
    for (int64_t i = 0; i < n; ++i) mean += src[i];
    mean /= double(n);
    for (int64_t i = 0; i < n; ++i) var += (src[i] - mean) * (src[i] - mean);
    const double inv = 1.0 / std::sqrt(var / double(n) + eps);
    for (int64_t c = gi * cg; c < (gi + 1) * cg; ++c)
      for (int64_t i = 0; i < x.H * x.W; ++i)
        y.plane(c)[i] = float((x.plane(c)[i] - mean) * inv) * g[size_t(c)] + b[size_t(c)];
  }
  return y;
}

void silu_inplace(Img& x) {
  for (float& v : x.d) v = silu(v);
}

Img nearest(const Img& x, int64_t H, int64_t W) {  // torch nearest: src = floor(dst · in / out)
  Img y(x.C, H, W);
  for (int64_t c = 0; c < x.C; ++c)
    for (int64_t i = 0; i < H; ++i)
      for (int64_t j = 0; j < W; ++j) y.plane(c)[i * W + j] = x.plane(c)[(i * x.H / H) * x.W + j * x.W / W];
  return y;
}

struct VaeRef {
  HostWeights& w;
  int64_t groups;
  float eps;
  const Img* zq = nullptr;  // decoder: SpatialNorm3D conditioning

  Img norm(const Img& x, const std::string& name) {
    if (!zq) return group_norm(x, w, name, groups, eps);
    Img n = group_norm(x, w, name + ".norm_layer", groups, eps);
    const Img z = nearest(*zq, x.H, x.W);
    const Img a = conv(z, w, name + ".conv_y.conv", 1, 1, 0, 0), b = conv(z, w, name + ".conv_b.conv", 1, 1, 0, 0);
    for (size_t i = 0; i < n.d.size(); ++i) n.d[i] = n.d[i] * a.d[i] + b.d[i];
    return n;
  }
  Img resnet(const Img& x, const std::string& p) {
    Img h = norm(x, p + ".norm1");
    silu_inplace(h);
    h = conv(h, w, p + ".conv1.conv", 3, 1, 1, 1);
    h = norm(h, p + ".norm2");
    silu_inplace(h);
    h = conv(h, w, p + ".conv2.conv", 3, 1, 1, 1);
    const Img s = w.has(p + ".conv_shortcut.weight") ? conv(x, w, p + ".conv_shortcut", 1, 1, 0, 0) : x;
    for (size_t i = 0; i < h.d.size(); ++i) h.d[i] += s.d[i];
    return h;
  }
};

Img to_img(const std::vector<float>& v, int64_t C, int64_t H, int64_t W) {
  Img x(C, H, W);
  x.d = v;
  return x;
}

}  // namespace

std::vector<float> vae_encode_reference(HostWeights& w, const nlohmann::json& cfg, const std::vector<float>& video,
                                        int64_t height, int64_t width) {
  const std::vector<int64_t> boc = cfg["block_out_channels"];
  const int64_t lpb = cfg["layers_per_block"], n = int64_t(boc.size());
  VaeRef r{w, cfg["norm_num_groups"].get<int64_t>(), cfg["norm_eps"].get<float>()};
  Img x = conv(to_img(video, cfg["in_channels"], height, width), w, "encoder.conv_in.conv", 3, 1, 1, 1);
  for (int64_t i = 0; i < n; ++i) {
    const std::string p = "encoder.down_blocks." + std::to_string(i);
    for (int64_t j = 0; j < lpb; ++j) x = r.resnet(x, p + ".resnets." + std::to_string(j));
    // CogVideoXDownsample3D on one frame: pad (0, 1, 0, 1), 3x3 stride-2 conv (the time pooling keeps frame 0).
    if (i + 1 < n) x = conv(x, w, p + ".downsamplers.0.conv", 3, 2, 0, 1);
  }
  for (int j = 0; j < 2; ++j) x = r.resnet(x, "encoder.mid_block.resnets." + std::to_string(j));
  x = group_norm(x, w, "encoder.norm_out", r.groups, r.eps);
  silu_inplace(x);
  return conv(x, w, "encoder.conv_out.conv", 3, 1, 1, 1).d;
}

std::vector<float> vae_decode_reference(HostWeights& w, const nlohmann::json& cfg, const std::vector<float>& z,
                                        int64_t height, int64_t width) {
  const std::vector<int64_t> boc = cfg["block_out_channels"];
  const int64_t lpb = cfg["layers_per_block"], n = int64_t(boc.size());
  const Img zq = to_img(z, cfg["latent_channels"], height, width);
  VaeRef r{w, cfg["norm_num_groups"].get<int64_t>(), cfg["norm_eps"].get<float>(), &zq};
  Img x = conv(zq, w, "decoder.conv_in.conv", 3, 1, 1, 1);
  for (int j = 0; j < 2; ++j) x = r.resnet(x, "decoder.mid_block.resnets." + std::to_string(j));
  for (int64_t i = 0; i < n; ++i) {
    const std::string p = "decoder.up_blocks." + std::to_string(i);
    for (int64_t j = 0; j <= lpb; ++j) x = r.resnet(x, p + ".resnets." + std::to_string(j));
    // CogVideoXUpsample3D on one frame: nearest 2x in space, 3x3 conv (padding 1).
    if (i + 1 < n) x = conv(nearest(x, 2 * x.H, 2 * x.W), w, p + ".upsamplers.0.conv", 3, 1, 1, 1);
  }
  x = r.norm(x, "decoder.norm_out");
  silu_inplace(x);
  return conv(x, w, "decoder.conv_out.conv", 3, 1, 1, 1).d;
}

}  // namespace dvs::bench::realsize
