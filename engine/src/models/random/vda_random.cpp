#include "models/random/vda_random.hpp"

#include <cmath>
#include <random>

namespace dvs {
namespace {

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

}  // namespace

std::vector<std::pair<std::string, Shape>> vda_checkpoint_schema(const VdaConfig& c) {
  std::vector<std::pair<std::string, Shape>> s;
  auto add = [&](std::string n, Shape sh) { s.emplace_back(std::move(n), std::move(sh)); };
  auto linear = [&](const std::string& n, int64_t out, int64_t in, bool bias) {
    add(n + ".weight", {out, in});
    if (bias) add(n + ".bias", {out});
  };
  auto conv = [&](const std::string& n, int64_t out, int64_t in, int64_t k, bool bias) {
    add(n + ".weight", {out, in, k, k});
    if (bias) add(n + ".bias", {out});
  };
  auto norm = [&](const std::string& n, int64_t ch) {
    add(n + ".weight", {ch});
    add(n + ".bias", {ch});
  };
  const int64_t D = c.embed_dim, grid = c.pos_embed_grid, ps = c.patch_size;
  add("pretrained.cls_token", {1, 1, D});
  add("pretrained.pos_embed", {1, 1 + grid * grid, D});
  add("pretrained.mask_token", {1, D});
  conv("pretrained.patch_embed.proj", D, 3, ps, true);
  for (int b = 0; b < c.depth; ++b) {
    const std::string p = "pretrained.blocks." + std::to_string(b) + ".";
    norm(p + "norm1", D);
    linear(p + "attn.qkv", 3 * D, D, true);
    linear(p + "attn.proj", D, D, true);
    add(p + "ls1.gamma", {D});
    norm(p + "norm2", D);
    linear(p + "mlp.fc1", c.mlp_hidden_dim, D, true);
    linear(p + "mlp.fc2", D, c.mlp_hidden_dim, true);
    add(p + "ls2.gamma", {D});
  }
  norm("pretrained.norm", D);
  const auto& oc = c.out_channels;
  for (int i = 0; i < 4; ++i) conv("head.projects." + std::to_string(i), oc[size_t(i)], D, 1, true);
  // Transposed convolutions are [in, out, k, k].
  add("head.resize_layers.0.weight", {oc[0], oc[0], 4, 4});
  add("head.resize_layers.0.bias", {oc[0]});
  add("head.resize_layers.1.weight", {oc[1], oc[1], 2, 2});
  add("head.resize_layers.1.bias", {oc[1]});
  conv("head.resize_layers.3", oc[3], oc[3], 3, true);
  const int64_t F = c.features;
  for (int i = 0; i < 4; ++i) conv("head.scratch.layer" + std::to_string(i + 1) + "_rn", F, oc[size_t(i)], 3, false);
  for (int i = 1; i <= 4; ++i) {
    const std::string p = "head.scratch.refinenet" + std::to_string(i) + ".";
    conv(p + "out_conv", F, F, 1, true);
    for (const char* unit : {"resConfUnit1.", "resConfUnit2."})
      for (const char* cv : {"conv1", "conv2"}) conv(p + unit + cv, F, F, 3, true);
  }
  conv("head.scratch.output_conv1", c.output_conv1_out, F, 3, true);
  conv("head.scratch.output_conv2.0", 32, c.output_conv1_out, 3, true);
  conv("head.scratch.output_conv2.2", 1, 32, 1, true);
  for (int m = 0; m < 4; ++m) {
    const int64_t C = c.temporal_channels[size_t(m)];
    const std::string p = "head.motion_modules." + std::to_string(m) + ".temporal_transformer.";
    norm(p + "norm", C);
    linear(p + "proj_in", C, C, true);
    const std::string t = p + "transformer_blocks.0.";
    for (int a = 0; a < 2; ++a) {
      const std::string q = t + "attention_blocks." + std::to_string(a) + ".";
      for (const char* w : {"to_q", "to_k", "to_v"}) linear(q + w, C, C, false);
      linear(q + "to_out.0", C, C, true);
      add(q + "pos_encoder.pe", {1, c.temporal_max_len, C});
    }
    for (int a = 0; a < 2; ++a) norm(t + "norms." + std::to_string(a), C);
    linear(t + "ff.net.0.proj", 8 * C, C, true);
    linear(t + "ff.net.2", C, 4 * C, true);
    norm(t + "ff_norm", C);
    linear(p + "proj_out", C, C, true);
  }
  return s;
}

std::vector<std::pair<std::string, HostTensor>> vda_random_checkpoint(const VdaConfig& c, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<float> normal(0.0f, 1.0f);
  std::vector<std::pair<std::string, HostTensor>> out;
  for (const auto& [name, shape] : vda_checkpoint_schema(c)) {
    HostTensor t(shape, DType::f32);
    float* v = t.as<float>();
    const int64_t n = t.numel();
    auto fill = [&](float mean, float sd) {
      for (int64_t i = 0; i < n; ++i) v[i] = mean + sd * normal(rng);
    };
    const bool weight = ends_with(name, ".weight"), is_norm = name.find("norm") != std::string::npos;
    if (ends_with(name, "pos_encoder.pe")) {
      // The sinusoidal table the class computes: pe[t, 2i] = sin(t·10000^(−2i/C)), pe[t, 2i+1] = cos(same).
      const int64_t T = shape[1], C = shape[2];
      for (int64_t p = 0; p < T; ++p)
        for (int64_t i = 0; i < C; i += 2) {
          const double f = std::exp(double(i) * (-std::log(10000.0) / double(C)));
          v[p * C + i] = float(std::sin(double(p) * f));
          if (i + 1 < C) v[p * C + i + 1] = float(std::cos(double(p) * f));
        }
    } else if (name == "pretrained.cls_token" || name == "pretrained.pos_embed" || name == "pretrained.mask_token") {
      fill(0.0f, 1.0f);
    } else if (ends_with(name, ".gamma")) {
      fill(0.5f, 0.2f);
    } else if (is_norm && weight && shape.size() == 1) {
      fill(1.0f, 0.1f);
    } else if (is_norm && ends_with(name, ".bias")) {
      fill(0.0f, 0.1f);
    } else if (name == "head.scratch.output_conv2.2.bias") {
      fill(0.6f, 0.05f);
    } else if (weight && name.rfind("head.resize_layers.", 0) == 0 && name != "head.resize_layers.3.weight") {
      fill(0.0f, 1.0f / std::sqrt(float(shape[0])));  // transposed: fan-in = input channels
    } else if (weight) {
      int64_t fan_in = 1;
      for (size_t i = 1; i < shape.size(); ++i) fan_in *= shape[i];
      fill(0.0f, 1.0f / std::sqrt(float(fan_in)));
    } else {
      fill(0.0f, 0.05f);
    }
    out.emplace_back(name, std::move(t));
  }
  return out;
}

}  // namespace dvs
