// T5 encoder and CogVideoX transformer on sizes the golden pack does not have (other head counts, a
// non-square latent grid, widths that are not multiples of 8, batch 2, T5 positions past the exact buckets),
// against plain double-precision C++ references written here. The random models are written to a temporary
// folder as config.json + model.safetensors, with exactly the tensors the schema of the config lists.
// Tolerance: |ours - ref| <= 1e-4 + 1e-3·|ref| (fp32 GPU arithmetic against double).
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <random>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "spec/model_schema.hpp"
#include "spec/model_folder.hpp"
#include "io/npy.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/lora.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "support/expect_error.hpp"
#include "support/gpu.hpp"
#include "tensor/ops_position.hpp"

namespace fs = std::filesystem;
using dvs::HostTensor;
using dvs::Shape;
using json = nlohmann::json;

namespace {

using Weights = std::map<std::string, std::vector<double>>;

// Random weights for every tensor of `schema`, initialised like the pack (fan-in scaled linears, norms ~1).
Weights random_weights(const dvs::Schema& schema, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  Weights w;
  for (const auto& t : schema.tensors) {
    if (t.optional) continue;
    std::vector<double> v(static_cast<size_t>(dvs::shape_numel(t.shape)));
    const bool norm = t.name.find("norm") != std::string::npos;
    double mean = 0, sd = 0.05;
    if (t.name.find("pos_embedding") != std::string::npos || t.name.find("relative_attention_bias") != std::string::npos)
      sd = 0.5;
    else if (t.name == "shared.weight")
      sd = 1.0;
    else if (t.shape.size() >= 2)
      sd = 1.0 / std::sqrt(double(dvs::shape_numel(t.shape) / t.shape[0]));
    else if (norm && t.name.size() > 7 && t.name.compare(t.name.size() - 7, 7, ".weight") == 0)
      mean = 1.0, sd = 0.1;
    else if (norm)
      sd = 0.1;
    for (double& x : v) x = mean + sd * n01(rng);
    // Round to f32 so the reference sees the values the engine uploads.
    for (double& x : v) x = double(float(x));
    w.emplace(t.name, std::move(v));
  }
  return w;
}

struct NamedTensor {
  std::string name;
  Shape shape;
  std::vector<double> values;
};

// A single-file F32 safetensors with the tensors in the given order.
void write_safetensors(const fs::path& file, const std::vector<NamedTensor>& tensors) {
  json header;
  uint64_t off = 0;
  for (const auto& t : tensors) {
    const uint64_t bytes = uint64_t(t.values.size()) * 4;
    header[t.name] = {{"dtype", "F32"}, {"shape", t.shape}, {"data_offsets", {off, off + bytes}}};
    off += bytes;
  }
  std::string h = header.dump();
  while (h.size() % 8) h += ' ';
  std::ofstream f(file, std::ios::binary);
  const uint64_t n = h.size();
  f.write(reinterpret_cast<const char*>(&n), 8);
  f.write(h.data(), std::streamsize(h.size()));
  for (const auto& t : tensors)
    for (double x : t.values) {
      const float v = float(x);
      f.write(reinterpret_cast<const char*>(&v), 4);
    }
}

void write_component(const fs::path& dir, const json& config, const Weights& w, const dvs::Schema& schema) {
  fs::create_directories(dir);
  std::ofstream(dir / "config.json") << config.dump(2);
  json header;
  uint64_t off = 0;
  for (const auto& t : schema.tensors) {
    if (!w.count(t.name)) continue;
    const uint64_t bytes = uint64_t(dvs::shape_numel(t.shape)) * 4;
    header[t.name] = {{"dtype", "F32"}, {"shape", t.shape}, {"data_offsets", {off, off + bytes}}};
    off += bytes;
  }
  std::string h = header.dump();
  while (h.size() % 8) h += ' ';
  std::ofstream f(dir / "model.safetensors", std::ios::binary);
  const uint64_t n = h.size();
  f.write(reinterpret_cast<const char*>(&n), 8);
  f.write(h.data(), std::streamsize(h.size()));
  for (const auto& t : schema.tensors) {
    auto it = w.find(t.name);
    if (it == w.end()) continue;
    for (double x : it->second) {
      const float v = float(x);
      f.write(reinterpret_cast<const char*>(&v), 4);
    }
  }
}

std::vector<double> normals(size_t n, uint32_t seed, double sd = 1.0) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> d(0.0, sd);
  std::vector<double> v(n);
  for (double& x : v) x = double(float(d(rng)));
  return v;
}

HostTensor host_f32(Shape s, const std::vector<double>& v) {
  std::vector<float> f(v.begin(), v.end());
  return HostTensor::from_f32(std::move(s), f);
}

void expect_near_ref(const std::string& what, const std::vector<float>& ours, const std::vector<double>& ref) {
  ASSERT_EQ(ours.size(), ref.size()) << what;
  double max_err = 0;
  size_t bad = 0;
  for (size_t i = 0; i < ref.size(); ++i) {
    const double e = std::fabs(double(ours[i]) - ref[i]);
    max_err = std::max(max_err, std::isnan(e) ? INFINITY : e);
    if (!(e <= 1e-4 + 1e-3 * std::fabs(ref[i]))) ++bad;
  }
  std::cout << "[reference] " << what << ": max |err| " << max_err << " over " << ref.size() << " values\n";
  EXPECT_EQ(bad, 0u) << what << ": max |err| " << max_err;
}

// ---- double references ----------------------------------------------------------------------------------

// y[r][o] = sum_i x[r][i] * W[o][i] (+ b[o])
std::vector<double> lin(const std::vector<double>& x, int64_t rows, int64_t in, const std::vector<double>& W,
                        int64_t out, const std::vector<double>* b = nullptr) {
  std::vector<double> y(static_cast<size_t>(rows * out));
  for (int64_t r = 0; r < rows; ++r)
    for (int64_t o = 0; o < out; ++o) {
      double s = b ? (*b)[size_t(o)] : 0.0;
      for (int64_t i = 0; i < in; ++i) s += x[size_t(r * in + i)] * W[size_t(o * in + i)];
      y[size_t(r * out + o)] = s;
    }
  return y;
}
double gelu_tanh(double x) { return 0.5 * x * (1 + std::tanh(std::sqrt(2 / M_PI) * (x + 0.044715 * x * x * x))); }
double silu(double x) { return x / (1 + std::exp(-x)); }

// softmax(q·kᵀ·scale + bias)·v for one head; q rows [Lq][stride] at column off, etc.
void attend(const std::vector<double>& qkv, int64_t stride, int64_t base_row, int64_t L, int64_t qoff, int64_t koff,
            int64_t voff, int64_t Dh, double scale, const std::function<double(int64_t, int64_t)>& bias,
            const std::function<bool(int64_t)>& key_ok, std::vector<double>& out, int64_t out_stride, int64_t out_off) {
  for (int64_t i = 0; i < L; ++i) {
    std::vector<double> s(static_cast<size_t>(L));
    double mx = -INFINITY;
    for (int64_t j = 0; j < L; ++j) {
      if (!key_ok(j)) continue;
      double d = 0;
      for (int64_t c = 0; c < Dh; ++c)
        d += qkv[size_t((base_row + i) * stride + qoff + c)] * qkv[size_t((base_row + j) * stride + koff + c)];
      s[size_t(j)] = d * scale + bias(i, j);
      mx = std::max(mx, s[size_t(j)]);
    }
    double den = 0;
    for (int64_t j = 0; j < L; ++j) den += key_ok(j) ? std::exp(s[size_t(j)] - mx) : 0.0;
    for (int64_t c = 0; c < Dh; ++c) {
      double acc = 0;
      for (int64_t j = 0; j < L; ++j)
        if (key_ok(j)) acc += std::exp(s[size_t(j)] - mx) / den * qkv[size_t((base_row + j) * stride + voff + c)];
      out[size_t((base_row + i) * out_stride + out_off + c)] = acc;
    }
  }
}

std::vector<double> t5_reference(const dvs::models::T5EncoderConfig& c, Weights& w,
                                 const std::vector<std::vector<int32_t>>& ids, const std::vector<std::vector<float>>& mask) {
  const int64_t B = int64_t(ids.size()), L = int64_t(ids[0].size()), D = c.d_model, I = c.inner(), H = c.num_heads;
  std::vector<double> h(static_cast<size_t>(B * L * D));
  for (int64_t r = 0; r < B * L; ++r)
    for (int64_t d = 0; d < D; ++d) h[size_t(r * D + d)] = w["shared.weight"][size_t(ids[size_t(r / L)][size_t(r % L)] * D + d)];
  auto rms = [&](const std::vector<double>& x, const std::vector<double>& g) {
    std::vector<double> y(x.size());
    for (int64_t r = 0; r < B * L; ++r) {
      double ss = 0;
      for (int64_t d = 0; d < D; ++d) ss += x[size_t(r * D + d)] * x[size_t(r * D + d)];
      const double inv = 1 / std::sqrt(ss / double(D) + c.eps);
      for (int64_t d = 0; d < D; ++d) y[size_t(r * D + d)] = x[size_t(r * D + d)] * inv * g[size_t(d)];
    }
    return y;
  };
  const auto& rel = w["encoder.block.0.layer.0.SelfAttention.relative_attention_bias.weight"];
  for (int64_t i = 0; i < c.num_layers; ++i) {
    const std::string p = "encoder.block." + std::to_string(i) + ".";
    const auto x = rms(h, w[p + "layer.0.layer_norm.weight"]);
    const auto q = lin(x, B * L, D, w[p + "layer.0.SelfAttention.q.weight"], I);
    const auto k = lin(x, B * L, D, w[p + "layer.0.SelfAttention.k.weight"], I);
    const auto v = lin(x, B * L, D, w[p + "layer.0.SelfAttention.v.weight"], I);
    std::vector<double> qkv(static_cast<size_t>(B * L * 3 * I));
    for (int64_t r = 0; r < B * L; ++r)
      for (int64_t d = 0; d < I; ++d) {
        qkv[size_t(r * 3 * I + d)] = q[size_t(r * I + d)];
        qkv[size_t(r * 3 * I + I + d)] = k[size_t(r * I + d)];
        qkv[size_t(r * 3 * I + 2 * I + d)] = v[size_t(r * I + d)];
      }
    std::vector<double> att(static_cast<size_t>(B * L * I));
    for (int64_t b = 0; b < B; ++b)
      for (int64_t hh = 0; hh < H; ++hh)
        attend(
            qkv, 3 * I, b * L, L, hh * c.d_kv, I + hh * c.d_kv, 2 * I + hh * c.d_kv, c.d_kv, 1.0,
            [&](int64_t qi, int64_t kj) {
              const int64_t bucket = dvs::models::t5_relative_position_bucket(kj - qi, true, c.num_buckets, c.max_distance);
              return rel[size_t(bucket * H + hh)];
            },
            [&](int64_t kj) { return mask.empty() || mask[size_t(b)][size_t(kj)] != 0; }, att, I, hh * c.d_kv);
    const auto o = lin(att, B * L, I, w[p + "layer.0.SelfAttention.o.weight"], D);
    for (size_t e = 0; e < h.size(); ++e) h[e] += o[e];
    const auto x2 = rms(h, w[p + "layer.1.layer_norm.weight"]);
    auto a = lin(x2, B * L, D, w[p + "layer.1.DenseReluDense.wi_0.weight"], c.d_ff);
    const auto u = lin(x2, B * L, D, w[p + "layer.1.DenseReluDense.wi_1.weight"], c.d_ff);
    for (size_t e = 0; e < a.size(); ++e) a[e] = gelu_tanh(a[e]) * u[e];
    const auto f = lin(a, B * L, c.d_ff, w[p + "layer.1.DenseReluDense.wo.weight"], D);
    for (size_t e = 0; e < h.size(); ++e) h[e] += f[e];
  }
  return rms(h, w["encoder.final_layer_norm.weight"]);
}

class ModelsText : public dvs::test::GpuTest {
 protected:
  fs::path tmp_dir(const std::string& name) {
    const fs::path d = fs::temp_directory_path() / ("dvs_models_text_" + std::to_string(::getpid()) + "_" + name);
    fs::remove_all(d);
    return d;
  }
};

}  // namespace

TEST_F(ModelsText, T5OtherSizesWithMaskAgainstReference) {
  // 3 heads of 8, d_model 24 and d_ff 40 (not multiples of 32), 8 buckets over max_distance 12 with L = 13 so
  // that the log-spaced and clamped buckets are used.
  const json config = {{"architectures", {"T5EncoderModel"}}, {"d_model", 24},     {"d_kv", 8},
                       {"d_ff", 40},                          {"num_heads", 3},    {"num_layers", 2},
                       {"vocab_size", 50},                    {"relative_attention_num_buckets", 8},
                       {"relative_attention_max_distance", 12}, {"feed_forward_proj", "gated-gelu"},
                       {"layer_norm_epsilon", 1e-6},          {"model_type", "t5"}};
  const dvs::Schema schema = dvs::t5_encoder_schema(config);
  Weights w = random_weights(schema, 7);
  const fs::path dir = tmp_dir("t5");
  write_component(dir, config, w, schema);
  dvs::models::T5Encoder t5(ctx(), dir);
  std::mt19937 rng(3);
  std::vector<std::vector<int32_t>> ids(2, std::vector<int32_t>(13));
  for (auto& row : ids)
    for (auto& id : row) id = int32_t(rng() % 50);
  std::vector<std::vector<float>> mask = {std::vector<float>(13, 1.0f), std::vector<float>(13, 1.0f)};
  for (int j = 9; j < 13; ++j) mask[1][size_t(j)] = 0.0f;
  const auto cfg = t5.config();
  expect_near_ref("t5 masked", t5.encode(ids, mask).download(ctx()).to_f32(), t5_reference(cfg, w, ids, mask));
  expect_near_ref("t5 no mask", t5.encode(ids).download(ctx()).to_f32(), t5_reference(cfg, w, ids, {}));
  fs::remove_all(dir);
}

// T5 with a d_kv that is not a multiple of 4 (6 and 5): the attention runs on head-padded copies of the fused
// q|k|v rows, whose column slices start at 3·d_kv·k (not multiples of 4), with the relative bias and the mask.
TEST_F(ModelsText, T5HeadDimNotMultipleOf4AgainstReference) {
  for (int64_t d_kv : {6, 5}) {
    const json config = {{"architectures", {"T5EncoderModel"}}, {"d_model", 20},     {"d_kv", d_kv},
                         {"d_ff", 28},                          {"num_heads", 3},    {"num_layers", 2},
                         {"vocab_size", 40},                    {"relative_attention_num_buckets", 8},
                         {"relative_attention_max_distance", 12}, {"feed_forward_proj", "gated-gelu"},
                         {"layer_norm_epsilon", 1e-6},          {"model_type", "t5"}};
    const dvs::Schema schema = dvs::t5_encoder_schema(config);
    Weights w = random_weights(schema, uint32_t(20 + d_kv));
    const fs::path dir = tmp_dir("t5_dkv" + std::to_string(d_kv));
    write_component(dir, config, w, schema);
    dvs::models::T5Encoder t5(ctx(), dir);
    std::mt19937 rng{uint32_t(d_kv)};
    std::vector<std::vector<int32_t>> ids(2, std::vector<int32_t>(11));
    for (auto& row : ids)
      for (auto& id : row) id = int32_t(rng() % 40);
    std::vector<std::vector<float>> mask = {std::vector<float>(11, 1.0f), std::vector<float>(11, 1.0f)};
    for (int j = 7; j < 11; ++j) mask[1][size_t(j)] = 0.0f;
    const auto cfg = t5.config();
    const std::string what = "t5 d_kv " + std::to_string(d_kv);
    expect_near_ref(what + " masked", t5.encode(ids, mask).download(ctx()).to_f32(), t5_reference(cfg, w, ids, mask));
    expect_near_ref(what + " no mask", t5.encode(ids).download(ctx()).to_f32(), t5_reference(cfg, w, ids, {}));
    fs::remove_all(dir);
  }
}

TEST_F(ModelsText, TransformerNonSquareOtherHeadsBatch2AgainstReference) {
  // 3 heads of 16 (D = 48), latent 2 x 6 x 10 (3 x 5 patches per frame), text 5 x 20, 6 -> 3 channels,
  // time_embed 20, batch 2 with different text and timesteps.
  const int64_t B = 2, F = 2, C = 6, Hh = 6, Ww = 10, L = 5, Tx = 20, nh = 3, Dh = 16, D = nh * Dh, T = 20, Co = 3;
  const int64_t p = 2, Hp = Hh / p, Wp = Ww / p, N = F * Hp * Wp, S = L + N, layers = 2;
  const json config = {{"_class_name", "CogVideoXTransformer3DModel"},
                       {"num_attention_heads", nh},
                       {"attention_head_dim", Dh},
                       {"in_channels", C},
                       {"out_channels", Co},
                       {"time_embed_dim", T},
                       {"text_embed_dim", Tx},
                       {"num_layers", layers},
                       {"sample_width", Ww},
                       {"sample_height", Hh},
                       {"sample_frames", (F - 1) * 4 + 1},
                       {"patch_size", p},
                       {"patch_size_t", nullptr},
                       {"temporal_compression_ratio", 4},
                       {"max_text_seq_length", L},
                       {"activation_fn", "gelu-approximate"},
                       {"timestep_activation_fn", "silu"},
                       {"norm_elementwise_affine", true},
                       {"norm_eps", 1e-5},
                       {"flip_sin_to_cos", true},
                       {"freq_shift", 0},
                       {"attention_bias", true},
                       {"use_rotary_positional_embeddings", true},
                       {"use_learned_positional_embeddings", true},
                       {"patch_bias", true},
                       {"ofs_embed_dim", nullptr}};
  const dvs::Schema schema = dvs::cogvideox_transformer_schema(config);
  Weights w = random_weights(schema, 11);
  const fs::path dir = tmp_dir("transformer");
  write_component(dir, config, w, schema);
  dvs::models::CogVideoXTransformer tr(ctx(), dir);

  const auto lat = normals(size_t(B * F * C * Hh * Ww), 21);
  const auto txt = normals(size_t(B * L * Tx), 22);
  const float ts[2] = {999.0f, 321.0f};
  const dvs::Tensor out = tr.forward(dvs::Tensor::upload(ctx(), host_f32({B, F, C, Hh, Ww}, lat)),
                                     dvs::Tensor::upload(ctx(), host_f32({B, L, Tx}, txt)), std::span<const float>(ts, 2));

  // Reference.
  const dvs::ops::RopeTables rope = dvs::ops::cogvideox_rope_tables(Dh, F, Hp, Wp, Hp, Wp);
  const auto rc = rope.cos.to_f32(), rs = rope.sin.to_f32();
  auto layer_norm = [&](std::vector<double>& x, int64_t rows, int64_t n, int64_t stride, int64_t off,
                        const std::vector<double>& g, const std::vector<double>& b, double eps) {
    for (int64_t r = 0; r < rows; ++r) {
      double m = 0, v = 0;
      for (int64_t d = 0; d < n; ++d) m += x[size_t(r * stride + off + d)];
      m /= double(n);
      for (int64_t d = 0; d < n; ++d) v += (x[size_t(r * stride + off + d)] - m) * (x[size_t(r * stride + off + d)] - m);
      const double inv = 1 / std::sqrt(v / double(n) + eps);
      for (int64_t d = 0; d < n; ++d)
        x[size_t(r * stride + off + d)] = (x[size_t(r * stride + off + d)] - m) * inv * g[size_t(d)] + b[size_t(d)];
    }
  };
  std::vector<double> ref(static_cast<size_t>(B * F * Co * Hh * Ww));
  for (int64_t b = 0; b < B; ++b) {
    // Time embedding.
    std::vector<double> tp(static_cast<size_t>(D));
    const int64_t half = D / 2;
    for (int64_t k = 0; k < half; ++k) {
      const float fr = std::exp(-std::log(10000.0f) * float(k) / float(half));
      const float arg = ts[b] * fr;
      tp[size_t(k)] = std::cos(double(arg));
      tp[size_t(half + k)] = std::sin(double(arg));
    }
    auto t1 = lin(tp, 1, D, w["time_embedding.linear_1.weight"], T, &w["time_embedding.linear_1.bias"]);
    for (double& x : t1) x = silu(x);
    auto emb = lin(t1, 1, T, w["time_embedding.linear_2.weight"], T, &w["time_embedding.linear_2.bias"]);
    for (double& x : emb) x = silu(x);
    // Sequence: text rows then patches, plus the learned table.
    std::vector<double> h(static_cast<size_t>(S * D));
    std::vector<double> tb(txt.begin() + b * L * Tx, txt.begin() + (b + 1) * L * Tx);
    const auto te = lin(tb, L, Tx, w["patch_embed.text_proj.weight"], D, &w["patch_embed.text_proj.bias"]);
    std::copy(te.begin(), te.end(), h.begin());
    const auto& pw = w["patch_embed.proj.weight"];
    for (int64_t f = 0; f < F; ++f)
      for (int64_t hp = 0; hp < Hp; ++hp)
        for (int64_t wp = 0; wp < Wp; ++wp)
          for (int64_t d = 0; d < D; ++d) {
            double s = w["patch_embed.proj.bias"][size_t(d)];
            for (int64_t c = 0; c < C; ++c)
              for (int64_t i = 0; i < p; ++i)
                for (int64_t j = 0; j < p; ++j)
                  s += pw[size_t(((d * C + c) * p + i) * p + j)] *
                       lat[size_t((((b * F + f) * C + c) * Hh + hp * p + i) * Ww + wp * p + j)];
            h[size_t((L + (f * Hp + hp) * Wp + wp) * D + d)] = s;
          }
    for (int64_t e = 0; e < S * D; ++e) h[size_t(e)] += w["patch_embed.pos_embedding"][size_t(e)];
    auto modulate = [&](std::vector<double>& x, const std::vector<double>& mod, int64_t set0_shift, int64_t set0_scale,
                        int64_t set1_shift, int64_t set1_scale) {
      for (int64_t r = 0; r < S; ++r) {
        const bool text = r < L;
        const int64_t sh = text ? set0_shift : set1_shift, sc = text ? set0_scale : set1_scale;
        for (int64_t d = 0; d < D; ++d)
          x[size_t(r * D + d)] = x[size_t(r * D + d)] * (1 + mod[size_t(sc + d)]) + mod[size_t(sh + d)];
      }
    };
    for (int64_t l = 0; l < layers; ++l) {
      const std::string pre = "transformer_blocks." + std::to_string(l) + ".";
      const auto m1 = lin(emb, 1, T, w[pre + "norm1.linear.weight"], 6 * D, &w[pre + "norm1.linear.bias"]);
      const auto m2 = lin(emb, 1, T, w[pre + "norm2.linear.weight"], 6 * D, &w[pre + "norm2.linear.bias"]);
      auto n = h;
      layer_norm(n, S, D, D, 0, w[pre + "norm1.norm.weight"], w[pre + "norm1.norm.bias"], 1e-5);
      modulate(n, m1, 3 * D, 4 * D, 0, D);
      const auto q = lin(n, S, D, w[pre + "attn1.to_q.weight"], D, &w[pre + "attn1.to_q.bias"]);
      const auto k = lin(n, S, D, w[pre + "attn1.to_k.weight"], D, &w[pre + "attn1.to_k.bias"]);
      const auto v = lin(n, S, D, w[pre + "attn1.to_v.weight"], D, &w[pre + "attn1.to_v.bias"]);
      std::vector<double> qkv(static_cast<size_t>(S * 3 * D));
      for (int64_t r = 0; r < S; ++r)
        for (int64_t d = 0; d < D; ++d) {
          qkv[size_t(r * 3 * D + d)] = q[size_t(r * D + d)];
          qkv[size_t(r * 3 * D + D + d)] = k[size_t(r * D + d)];
          qkv[size_t(r * 3 * D + 2 * D + d)] = v[size_t(r * D + d)];
        }
      for (int64_t hh = 0; hh < nh; ++hh) {
        layer_norm(qkv, S, Dh, 3 * D, hh * Dh, w[pre + "attn1.norm_q.weight"], w[pre + "attn1.norm_q.bias"], 1e-6);
        layer_norm(qkv, S, Dh, 3 * D, D + hh * Dh, w[pre + "attn1.norm_k.weight"], w[pre + "attn1.norm_k.bias"], 1e-6);
      }
      for (int64_t r = L; r < S; ++r)
        for (int64_t part = 0; part < 2; ++part)
          for (int64_t hh = 0; hh < nh; ++hh)
            for (int64_t i = 0; i < Dh; i += 2) {
              double* x = &qkv[size_t(r * 3 * D + part * D + hh * Dh + i)];
              const size_t t = size_t((r - L) * Dh + i);
              const double x0 = x[0], x1 = x[1];
              x[0] = x0 * rc[t] - x1 * rs[t];
              x[1] = x1 * rc[t + 1] + x0 * rs[t + 1];
            }
      std::vector<double> att(static_cast<size_t>(S * D));
      for (int64_t hh = 0; hh < nh; ++hh)
        attend(
            qkv, 3 * D, 0, S, hh * Dh, D + hh * Dh, 2 * D + hh * Dh, Dh, 1 / std::sqrt(double(Dh)),
            [](int64_t, int64_t) { return 0.0; }, [](int64_t) { return true; }, att, D, hh * Dh);
      const auto o = lin(att, S, D, w[pre + "attn1.to_out.0.weight"], D, &w[pre + "attn1.to_out.0.bias"]);
      for (int64_t r = 0; r < S; ++r)
        for (int64_t d = 0; d < D; ++d) h[size_t(r * D + d)] += m1[size_t((r < L ? 5 : 2) * D + d)] * o[size_t(r * D + d)];
      auto n2 = h;
      layer_norm(n2, S, D, D, 0, w[pre + "norm2.norm.weight"], w[pre + "norm2.norm.bias"], 1e-5);
      modulate(n2, m2, 3 * D, 4 * D, 0, D);
      auto f1 = lin(n2, S, D, w[pre + "ff.net.0.proj.weight"], 4 * D, &w[pre + "ff.net.0.proj.bias"]);
      for (double& x : f1) x = gelu_tanh(x);
      const auto f2 = lin(f1, S, 4 * D, w[pre + "ff.net.2.weight"], D, &w[pre + "ff.net.2.bias"]);
      for (int64_t r = 0; r < S; ++r)
        for (int64_t d = 0; d < D; ++d) h[size_t(r * D + d)] += m2[size_t((r < L ? 5 : 2) * D + d)] * f2[size_t(r * D + d)];
    }
    layer_norm(h, S, D, D, 0, w["norm_final.weight"], w["norm_final.bias"], 1e-5);
    layer_norm(h, S, D, D, 0, w["norm_out.norm.weight"], w["norm_out.norm.bias"], 1e-5);
    const auto mo = lin(emb, 1, T, w["norm_out.linear.weight"], 2 * D, &w["norm_out.linear.bias"]);
    modulate(h, mo, 0, D, 0, D);
    std::vector<double> hv(h.begin() + L * D, h.end());
    const int64_t P = p * p * Co;
    const auto po = lin(hv, N, D, w["proj_out.weight"], P, &w["proj_out.bias"]);
    for (int64_t f = 0; f < F; ++f)
      for (int64_t hp = 0; hp < Hp; ++hp)
        for (int64_t wp = 0; wp < Wp; ++wp)
          for (int64_t c = 0; c < Co; ++c)
            for (int64_t i = 0; i < p; ++i)
              for (int64_t j = 0; j < p; ++j)
                ref[size_t((((b * F + f) * Co + c) * Hh + hp * p + i) * Ww + wp * p + j)] =
                    po[size_t(((f * Hp + hp) * Wp + wp) * P + (c * p + i) * p + j)];
  }
  expect_near_ref("transformer", out.download(ctx()).to_f32(), ref);
  fs::remove_all(dir);
}

TEST_F(ModelsText, TransformerRejectsSizesDiffusersRejects) {
  // The pack's model has a learned positional embedding for 3 latent frames of 8 x 8.
  const fs::path dir = fs::path(dvs::test::golden_dir()) / "model" / "transformer";
  if (!fs::exists(dir)) GTEST_SKIP() << "no golden pack";
  dvs::models::CogVideoXTransformer tr(ctx(), dir);
  EXPECT_THROW(tr.positional_embedding(3, 8, 10, 8), dvs::Error);  // other resolution
  EXPECT_THROW(tr.positional_embedding(3, 8, 8, 7), dvs::Error);   // text shorter than max_text_seq_length
  EXPECT_NO_THROW(tr.positional_embedding(3, 8, 8, 8));
}

// Measurement, not a check (skipped unless DVS_MEASURE_MODELS=1): forward time of both models at a mid size
// with random weights. Transformer: 4 layers, 4 heads x 64, I2V channels 32 -> 16, latent 13 x 30 x 44,
// text 226 x 4096, time_embed 512. T5: 4 layers, 8 heads x 64, d_model 512, d_ff 1024, 226 tokens.
TEST_F(ModelsText, MidSizeForwardTime) {
  if (!std::getenv("DVS_MEASURE_MODELS")) GTEST_SKIP() << "set DVS_MEASURE_MODELS=1 to measure";
  using clock = std::chrono::steady_clock;
  auto ms_since = [](clock::time_point t0) { return std::chrono::duration<double, std::milli>(clock::now() - t0).count(); };
  {
    const int64_t F = 13, C = 32, Hh = 30, Ww = 44, L = 226, Tx = 4096;
    const json config = {{"_class_name", "CogVideoXTransformer3DModel"}, {"num_attention_heads", 4},
                         {"attention_head_dim", 64}, {"in_channels", C}, {"out_channels", 16}, {"time_embed_dim", 512},
                         {"text_embed_dim", Tx}, {"num_layers", 4}, {"sample_width", Ww}, {"sample_height", Hh},
                         {"sample_frames", 49}, {"patch_size", 2}, {"patch_size_t", nullptr},
                         {"temporal_compression_ratio", 4}, {"max_text_seq_length", L},
                         {"activation_fn", "gelu-approximate"}, {"timestep_activation_fn", "silu"},
                         {"norm_elementwise_affine", true}, {"norm_eps", 1e-5}, {"flip_sin_to_cos", true},
                         {"freq_shift", 0}, {"attention_bias", true}, {"use_rotary_positional_embeddings", true},
                         {"use_learned_positional_embeddings", true}, {"patch_bias", true}, {"ofs_embed_dim", nullptr}};
    const dvs::Schema schema = dvs::cogvideox_transformer_schema(config);
    const fs::path dir = tmp_dir("mid_transformer");
    write_component(dir, config, random_weights(schema, 5), schema);
    dvs::models::CogVideoXTransformer tr(ctx(), dir);
    for (int64_t B : {int64_t(1), int64_t(2)}) {
      const dvs::Tensor lat = dvs::Tensor::upload(ctx(), host_f32({B, F, C, Hh, Ww}, normals(size_t(B * F * C * Hh * Ww), 1)));
      const dvs::Tensor txt = dvs::Tensor::upload(ctx(), host_f32({B, L, Tx}, normals(size_t(B * L * Tx), 2)));
      const float t = 500.0f;
      if (B == 1) tr.forward(lat, txt, std::span<const float>(&t, 1));  // warm-up (pipelines, tables, arena)
      const auto t0 = clock::now();
      tr.forward(lat, txt, std::span<const float>(&t, 1));
      std::cout << "[timing] transformer mid size B=" << B << " latent " << lat.describe() << ": " << ms_since(t0)
                << " ms per forward, arena " << tr.arena_bytes(B, F, Hh, Ww, L) / 1048576.0 << " MiB ("
                << ctx().caps().name << ")\n";
    }
    fs::remove_all(dir);
  }
  {
    const json config = {{"architectures", {"T5EncoderModel"}}, {"d_model", 512}, {"d_kv", 64}, {"d_ff", 1024},
                         {"num_heads", 8}, {"num_layers", 4}, {"vocab_size", 1000},
                         {"relative_attention_num_buckets", 32}, {"relative_attention_max_distance", 128},
                         {"feed_forward_proj", "gated-gelu"}, {"layer_norm_epsilon", 1e-6}};
    const dvs::Schema schema = dvs::t5_encoder_schema(config);
    const fs::path dir = tmp_dir("mid_t5");
    write_component(dir, config, random_weights(schema, 6), schema);
    dvs::models::T5Encoder t5(ctx(), dir);
    std::vector<std::vector<int32_t>> ids(2, std::vector<int32_t>(226, 0));
    for (size_t i = 0; i < 226; ++i) ids[0][i] = ids[1][i] = int32_t((i * 37) % 1000);
    t5.encode(ids);  // warm-up
    const auto t0 = clock::now();
    t5.encode(ids);
    std::cout << "[timing] T5 mid size B=2 L=226 d_model 512 x 4 layers: " << ms_since(t0) << " ms per encode\n";
    fs::remove_all(dir);
  }
}

// Memory plan from the configs alone (printed, not asserted beyond sanity): activation arenas of the real
// CogVideoX-5B-I2V transformer at 480x720x49 (latent 13x60x90, CFG batch 2, 226 text tokens) and of T5-XXL.
TEST(ModelsTextPlan, RealSizeActivationArenas) {
  const json tr_cfg = {{"num_attention_heads", 48}, {"attention_head_dim", 64}, {"in_channels", 32},
                       {"out_channels", 16}, {"time_embed_dim", 512}, {"text_embed_dim", 4096}, {"num_layers", 42},
                       {"sample_width", 90}, {"sample_height", 60}, {"sample_frames", 49}, {"patch_size", 2},
                       {"max_text_seq_length", 226}, {"use_rotary_positional_embeddings", true},
                       {"use_learned_positional_embeddings", true}};
  const auto tc = dvs::models::CogVideoXTransformerConfig::from_json(tr_cfg);
  const uint64_t tr_bytes = dvs::models::CogVideoXTransformer::arena_bytes(tc, 256, 2, 13, 60, 90, 226);
  const json t5_cfg = {{"d_model", 4096}, {"d_kv", 64}, {"d_ff", 10240}, {"num_heads", 64}, {"num_layers", 24},
                       {"vocab_size", 32128}, {"feed_forward_proj", "gated-gelu"}};
  const auto c5 = dvs::models::T5EncoderConfig::from_json(t5_cfg);
  const uint64_t t5_bytes = dvs::models::T5Encoder::arena_bytes(c5, true, 256, 2, 226);
  std::cout << "[plan] CogVideoX-5B-I2V transformer activations, B=2 x (226 + 17550) tokens: " << tr_bytes / 1048576.0
            << " MiB\n[plan] T5-XXL encoder activations, B=2 x 226 tokens: " << t5_bytes / 1048576.0 << " MiB\n";
  // The sequence, its norm, K and V [B, S, D] dominate (4·B·S·D·4 bytes); q, the attention output and the FFN
  // state exist for one token chunk at a time, at most half the sequence's bytes: ~4.5·B·S·D·4 in all.
  const double seq = 2.0 * (226 + 13 * 30 * 45) * 3072 * 4;
  EXPECT_GT(double(tr_bytes), 4.5 * seq);
  EXPECT_LT(double(tr_bytes), 4.7 * seq);
  EXPECT_GT(t5_bytes, 0u);
  // At the Vulkan 1.1 minimum (1 GiB allocations, 128 MiB bindings) every tensor fits one allocation: the arena is
  // blocks of at most 1 GiB and the chunks shrink to one binding's FFN state.
  const uint64_t GiB = 1ull << 30, MiB = 1ull << 20;
  const dvs::vk::ArenaLayout min_profile =
      dvs::models::CogVideoXTransformer::arena_layout(tc, 256, 2, 13, 60, 90, 226, 0, GiB, 128 * MiB);
  EXPECT_LE(min_profile.largest, 437 * MiB);
  for (const auto b : min_profile.blocks) EXPECT_LE(b, GiB);
  EXPECT_LT(min_profile.bytes(), tr_bytes);
  EXPECT_EQ(dvs::models::CogVideoXTransformer::token_chunk(tc, 2, 226 + 17550, 128 * MiB), 1365);
  std::cout << "[plan] the same under 1 GiB allocations and 128 MiB bindings: " << min_profile.bytes() / 1048576.0
            << " MiB\n";
  // Below the sequence's own size no chunking helps: the error names the arena and the tensor.
  dvs::test::expect_error(
      [&] { dvs::models::CogVideoXTransformer::arena_bytes(tc, 256, 2, 13, 60, 90, 226, 0, 256 * MiB, 128 * MiB); },
      {"transformer activation arena", "17776", "maxMemoryAllocationSize 256.0 MiB"});
}

// Another frame count than sample_frames: diffusers replaces the learned table by a 3D sincos one.
TEST_F(ModelsText, SincosPositionalEmbeddingForOtherFrameCounts) {
  const fs::path dir = fs::path(dvs::test::golden_dir()) / "model" / "transformer";
  if (!fs::exists(dir)) GTEST_SKIP() << "no golden pack";
  dvs::models::CogVideoXTransformer tr(ctx(), dir);
  const auto& cfg = tr.config();
  const int64_t D = cfg.dim(), L = cfg.max_text_seq_length, F = 2, Hp = cfg.sample_height / 2, Wp = cfg.sample_width / 2;
  const auto v = tr.positional_embedding(F, cfg.sample_height, cfg.sample_width, L).download(ctx()).to_f32();
  ASSERT_EQ(int64_t(v.size()), (L + F * Hp * Wp) * D);
  for (int64_t i = 0; i < L * D; ++i) ASSERT_EQ(v[size_t(i)], 0.0f) << "text rows are zero";
  // Token (f, i, j) = (1, 2, 3): [t | w | h] parts, each [sin | cos] with omega_k = 10000^(-k / (e/2)).
  const int64_t f = 1, i = 2, j = 3, Dt = D / 4, Ds = 3 * D / 8;
  const float* row = v.data() + (L + (f * Hp + i) * Wp + j) * D;
  auto check = [&](const float* part, int64_t e, double pos, const char* what) {
    for (int64_t k = 0; k < e / 2; ++k) {
      const double a = pos * std::pow(10000.0, -double(k) / (double(e) / 2.0));
      EXPECT_NEAR(part[k], std::sin(a), 1e-6) << what << " sin " << k;
      EXPECT_NEAR(part[e / 2 + k], std::cos(a), 1e-6) << what << " cos " << k;
    }
  };
  check(row, Dt, double(f) / cfg.temporal_interpolation_scale, "t");
  check(row + Dt, Ds, double(float(j) / cfg.spatial_interpolation_scale), "w");
  check(row + Dt + Ds, Ds, double(float(i) / cfg.spatial_interpolation_scale), "h");
  // The forward runs with it (2 latent frames instead of 3).
  const dvs::Tensor lat = dvs::Tensor::upload(ctx(), host_f32({1, F, cfg.in_channels, cfg.sample_height, cfg.sample_width},
                                                              normals(size_t(F * cfg.in_channels * Hp * Wp * 4), 9)));
  const dvs::Tensor txt = dvs::Tensor::upload(ctx(), host_f32({1, L, cfg.text_embed_dim}, normals(size_t(L * cfg.text_embed_dim), 10)));
  const float t = 500.0f;
  const auto out = tr.forward(lat, txt, std::span<const float>(&t, 1)).download(ctx()).to_f32();
  for (float x : out) ASSERT_TRUE(std::isfinite(x));
}

// LoRA applied unmerged (two extra GEMMs per projection) equals the same model with W + scale·(alpha/r)·B·A
// merged by hand into its weights. The pack's tiny transformer; adapters on q and v of block 0, k and out of
// block 1 (the latter with an alpha entry).
TEST_F(ModelsText, LoraUnmergedEqualsWeightsMergedByHand) {
  const fs::path pack = fs::path(dvs::test::golden_dir());
  const fs::path dir = pack / "model" / "transformer";
  if (!fs::exists(dir)) GTEST_SKIP() << "no golden pack";
  const dvs::WeightSet ws = dvs::WeightSet::open_dir(dir);
  std::ifstream cf(dir / "config.json");
  const json config = json::parse(cf);
  const int64_t D = config.at("num_attention_heads").get<int64_t>() * config.at("attention_head_dim").get<int64_t>();
  const int64_t r = 4;
  const float user_scale = 0.7f;
  struct Target {
    std::string module;
    double alpha;  // 0: no alpha entry
  };
  const std::vector<Target> targets = {{"transformer_blocks.0.attn1.to_q", 0},
                                       {"transformer_blocks.0.attn1.to_v", 0},
                                       {"transformer_blocks.1.attn1.to_k", 0},
                                       {"transformer_blocks.1.attn1.to_out.0", 8}};
  std::vector<NamedTensor> lora;
  std::map<std::string, std::pair<std::vector<double>, std::vector<double>>> ab;
  uint32_t seed = 100;
  for (const auto& t : targets) {
    auto a = normals(size_t(r * D), seed++, 1.0 / std::sqrt(double(D)));
    auto b = normals(size_t(D * r), seed++, 0.5);
    lora.push_back({"transformer." + t.module + ".lora_A.weight", {r, D}, a});
    lora.push_back({"transformer." + t.module + ".lora_B.weight", {D, r}, b});
    if (t.alpha > 0) lora.push_back({"transformer." + t.module + ".alpha", {}, {t.alpha}});
    ab[t.module] = {a, b};
  }
  const fs::path tmp = tmp_dir("lora");
  fs::create_directories(tmp / "merged");
  write_safetensors(tmp / "lora.safetensors", lora);
  std::ofstream(tmp / "merged" / "config.json") << config.dump(2);
  std::vector<NamedTensor> merged;
  for (const auto& [name, ref] : ws.entries()) {
    const HostTensor h = ws.load(name);
    const auto f = h.to_f32();
    NamedTensor t{name, h.shape, std::vector<double>(f.begin(), f.end())};
    for (const auto& tg : targets)
      if (name == tg.module + ".weight") {
        const double s = user_scale * (tg.alpha > 0 ? tg.alpha / double(r) : 1.0);
        const auto& [a, b] = ab[tg.module];
        for (int64_t o = 0; o < D; ++o)
          for (int64_t i = 0; i < D; ++i) {
            double d = 0;
            for (int64_t k = 0; k < r; ++k) d += b[size_t(o * r + k)] * a[size_t(k * D + i)];
            t.values[size_t(o * D + i)] += s * d;
          }
      }
    merged.push_back(std::move(t));
  }
  write_safetensors(tmp / "merged" / "diffusion_pytorch_model.safetensors", merged);

  const HostTensor lat = dvs::read_npy(pack / "transformer" / "hidden_states.npy");
  const HostTensor txt = dvs::read_npy(pack / "transformer" / "encoder_hidden_states.npy");
  const float t = 999.0f;
  auto run = [&](dvs::models::CogVideoXTransformer& tr) {
    return tr.forward(dvs::Tensor::upload(ctx(), lat), dvs::Tensor::upload(ctx(), txt), std::span<const float>(&t, 1))
        .download(ctx())
        .to_f32();
  };
  dvs::models::CogVideoXTransformer with_lora(ctx(), dir);
  const auto base = run(with_lora);
  with_lora.set_lora(dvs::models::load_lora(ctx(), tmp / "lora.safetensors", user_scale));
  const auto ours = run(with_lora);
  dvs::models::CogVideoXTransformer by_hand(ctx(), tmp / "merged");
  const auto ref = run(by_hand);
  double max_err = 0, max_effect = 0;
  for (size_t i = 0; i < ref.size(); ++i) {
    max_err = std::max(max_err, std::fabs(double(ours[i]) - double(ref[i])));
    max_effect = std::max(max_effect, std::fabs(double(ref[i]) - double(base[i])));
    EXPECT_LE(std::fabs(double(ours[i]) - double(ref[i])), 1e-5 + 1e-4 * std::fabs(double(ref[i]))) << i;
  }
  std::cout << "[lora] unmerged vs merged by hand: max |err| " << max_err << "; LoRA moves the output by up to "
            << max_effect << "\n";
  EXPECT_GT(max_effect, 1e-2) << "the LoRA must change the output";
  with_lora.clear_lora();
  const auto again = run(with_lora);
  for (size_t i = 0; i < base.size(); ++i) ASSERT_EQ(again[i], base[i]);
  EXPECT_THROW(with_lora.set_lora({{"transformer_blocks.0.ff.net.2", dvs::models::LoraAdapter{}}}), dvs::Error);
  fs::remove_all(tmp);
}
