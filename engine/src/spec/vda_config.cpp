#include "spec/vda_config.hpp"

#include <set>

#include "dvs/error.hpp"
#include "spec/model_folder.hpp"

namespace dvs {

namespace {

struct ReleasedSize {
  const char* name;
  int embed_dim, depth, num_heads;
  std::array<int, 4> taps;
  int features;
  std::array<int, 4> out_channels;
};

// The pack README's table (upstream: video_depth.py / run.py model_configs and intermediate_layer_idx).
constexpr std::array<ReleasedSize, 3> kReleased{{
    {"vits", 384, 12, 6, {2, 5, 8, 11}, 64, {48, 96, 192, 384}},
    {"vitb", 768, 12, 12, {2, 5, 8, 11}, 128, {96, 192, 384, 768}},
    {"vitl", 1024, 24, 16, {4, 11, 17, 23}, 256, {256, 512, 1024, 1024}},
}};

void derive(VdaConfig& c) {
  c.head_dim = c.num_heads > 0 ? c.embed_dim / c.num_heads : 0;
  if (c.mlp_hidden_dim == 0) c.mlp_hidden_dim = 4 * c.embed_dim;
  if (c.output_conv1_out == 0) c.output_conv1_out = c.features / 2;
  c.temporal_channels = {c.out_channels[2], c.out_channels[3], c.features, c.features};
}

// What the tensors say about the architecture; -1 where a tensor is absent.
struct Observed {
  int embed_dim = -1, depth = 0, features = -1, pe_len = -1;
  std::array<int, 4> out_channels{-1, -1, -1, -1};
};

Observed observe(const std::map<std::string, Shape>& shapes, const std::string& file) {
  Observed o;
  auto dim = [&](const char* name, size_t rank, size_t axis) -> int {
    auto it = shapes.find(name);
    if (it == shapes.end()) return -1;
    if (it->second.size() != rank)
      throw Error(file + ": tensor " + name + " has shape " + shape_str(it->second) + ", expected " +
                  std::to_string(rank) + " dimensions: not a Video-Depth-Anything checkpoint");
    return int(it->second[axis]);
  };
  o.embed_dim = dim("pretrained.cls_token", 3, 2);
  if (o.embed_dim < 0) o.embed_dim = dim("pretrained.patch_embed.proj.weight", 4, 0);
  if (o.embed_dim < 0)
    throw Error(file + ": no pretrained.cls_token or pretrained.patch_embed.proj.weight: not a Video-Depth-Anything "
                "checkpoint (keys pretrained.* and head.*)");
  std::set<int> blocks;
  const std::string prefix = "pretrained.blocks.";
  for (const auto& [name, s] : shapes) {
    if (name.rfind(prefix, 0) != 0) continue;
    const size_t dot = name.find('.', prefix.size());
    try {
      blocks.insert(std::stoi(name.substr(prefix.size(), dot - prefix.size())));
    } catch (const std::exception&) {
      throw Error(file + ": tensor " + name + " has no block number");
    }
  }
  o.depth = int(blocks.size());
  if (o.depth == 0 || *blocks.begin() != 0 || *blocks.rbegin() != o.depth - 1)
    throw Error(file + ": the encoder blocks pretrained.blocks.<i> are not numbered 0.." + std::to_string(o.depth - 1) +
                " (found " + std::to_string(o.depth) + " distinct numbers)");
  o.features = dim("head.scratch.layer1_rn.weight", 4, 0);
  for (int i = 0; i < 4; ++i) o.out_channels[size_t(i)] = dim(("head.projects." + std::to_string(i) + ".weight").c_str(), 4, 0);
  o.pe_len = dim("head.motion_modules.0.temporal_transformer.transformer_blocks.0.attention_blocks.0.pos_encoder.pe", 3, 1);
  return o;
}

std::string arr(const std::array<int, 4>& a) {
  std::string s = "[";
  for (size_t i = 0; i < a.size(); ++i) {
    if (i) s += ", ";
    s += std::to_string(a[i]);
  }
  s += "]";
  return s;
}

}  // namespace

VdaConfig released_vda_config(const std::string& name) {
  for (const auto& r : kReleased) {
    if (name != r.name) continue;
    VdaConfig c;
    c.name = r.name;
    c.origin = std::string("released size ") + r.name;
    c.embed_dim = r.embed_dim;
    c.depth = r.depth;
    c.num_heads = r.num_heads;
    c.taps = r.taps;
    c.features = r.features;
    c.out_channels = r.out_channels;
    derive(c);
    return c;
  }
  throw Error("'" + name + "' is not a released Video-Depth-Anything size (vits, vitb or vitl)");
}

VdaConfig recognise_vda_size(const std::map<std::string, Shape>& shapes, const std::filesystem::path& file) {
  const Observed o = observe(shapes, file.string());
  for (const auto& r : kReleased) {
    if (o.embed_dim != r.embed_dim || o.depth != r.depth) continue;
    if (o.features != r.features || o.out_channels != r.out_channels)
      throw Error(file.string() + ": encoder of " + r.name + " (embed dim " + std::to_string(r.embed_dim) + ", " +
                  std::to_string(r.depth) + " blocks) but a DPT head with features " + std::to_string(o.features) +
                  " and out_channels " + arr(o.out_channels) + " instead of " + std::to_string(r.features) + " and " +
                  arr(r.out_channels) + ": not a released size; put a config.json (schema of the conformance pack's "
                  "model/config.json) beside the checkpoint to describe it");
    VdaConfig c = released_vda_config(r.name);
    c.origin = "recognised from the tensors of " + file.string();
    c.metric = file.filename().string().rfind("metric_", 0) == 0;
    if (o.pe_len > 0) c.temporal_max_len = o.pe_len;
    return c;
  }
  throw Error(file.string() + ": embed dim " + std::to_string(o.embed_dim) + " with " + std::to_string(o.depth) +
              " encoder blocks is not a released Video-Depth-Anything size (vits: 384 / 12, vitb: 768 / 12, vitl: "
              "1024 / 24); put a config.json beside the checkpoint describing its architecture (schema of the "
              "conformance pack's model/config.json: encoder.embed_dim, depth, num_heads, intermediate_layer_idx, "
              "head.features, out_channels)");
}

VdaConfig vda_config_from_json(const nlohmann::json& j, const std::string& origin) {
  VdaConfig c;
  c.origin = origin;
  auto section = [&](const char* name) -> const nlohmann::json& {
    if (!j.contains(name) || !j[name].is_object()) throw Error(origin + ": no \"" + std::string(name) + "\" object");
    return j[name];
  };
  auto integer = [&](const nlohmann::json& s, const char* sec, const char* key, int lo, int hi, bool required, int& out) {
    if (!s.contains(key)) {
      if (required) throw Error(origin + ": " + sec + "." + key + " is missing");
      return;
    }
    if (!s[key].is_number_integer() || s[key].get<int64_t>() < lo || s[key].get<int64_t>() > hi)
      throw Error(origin + ": " + sec + "." + key + " must be a whole number in [" + std::to_string(lo) + ", " +
                  std::to_string(hi) + "], got " + s[key].dump());
    out = s[key].get<int>();
  };
  auto number = [&](const nlohmann::json& s, const char* sec, const char* key, float& out) {
    if (!s.contains(key)) return;
    if (!s[key].is_number() || !(s[key].get<double>() > 0))
      throw Error(origin + ": " + sec + "." + key + " must be a positive number, got " + s[key].dump());
    out = s[key].get<float>();
  };
  auto four = [&](const nlohmann::json& s, const char* sec, const char* key, int lo, int hi, bool required,
                  std::array<int, 4>& out) {
    if (!s.contains(key)) {
      if (required) throw Error(origin + ": " + sec + "." + key + " is missing");
      return;
    }
    const auto& a = s[key];
    if (!a.is_array() || a.size() != 4) throw Error(origin + ": " + sec + "." + key + " must be a list of 4 numbers");
    for (size_t i = 0; i < 4; ++i) {
      if (!a[i].is_number_integer() || a[i].get<int64_t>() < lo || a[i].get<int64_t>() > hi)
        throw Error(origin + ": " + sec + "." + key + "[" + std::to_string(i) + "] must be a whole number in [" +
                    std::to_string(lo) + ", " + std::to_string(hi) + "], got " + a[i].dump());
      out[i] = a[i].get<int>();
    }
  };
  try {
    const auto& enc = section("encoder");
    const auto& head = section("head");
    if (enc.contains("name") && enc["name"].is_string()) c.name = enc["name"].get<std::string>();
    else c.name = "custom";
    integer(enc, "encoder", "embed_dim", 1, 1 << 16, true, c.embed_dim);
    integer(enc, "encoder", "depth", 1, 1024, true, c.depth);
    integer(enc, "encoder", "num_heads", 1, 1 << 16, true, c.num_heads);
    integer(enc, "encoder", "mlp_hidden_dim", 1, 1 << 20, false, c.mlp_hidden_dim);
    integer(enc, "encoder", "patch_size", 1, 1024, false, c.patch_size);
    integer(enc, "encoder", "pos_embed_grid", 1, 4096, false, c.pos_embed_grid);
    four(enc, "encoder", "intermediate_layer_idx", 0, c.depth - 1, true, c.taps);
    integer(head, "head", "features", 2, 1 << 16, true, c.features);
    four(head, "head", "out_channels", 1, 1 << 16, true, c.out_channels);
    integer(head, "head", "output_conv1_out", 1, 1 << 16, false, c.output_conv1_out);
    if (c.embed_dim % c.num_heads)
      throw Error(origin + ": encoder.embed_dim " + std::to_string(c.embed_dim) + " is not a multiple of num_heads " +
                  std::to_string(c.num_heads));
    for (size_t i = 1; i < 4; ++i)
      if (c.taps[i] <= c.taps[i - 1])
        throw Error(origin + ": encoder.intermediate_layer_idx " + arr(c.taps) + " must be strictly increasing");
    derive(c);
    if (enc.contains("head_dim") && enc["head_dim"] != c.head_dim)
      throw Error(origin + ": encoder.head_dim " + enc["head_dim"].dump() + " is not embed_dim / num_heads = " +
                  std::to_string(c.head_dim));
    if (j.contains("temporal")) {
      const auto& t = j["temporal"];
      std::array<int, 4> ch = c.temporal_channels;
      four(t, "temporal", "channels", 1, 1 << 16, false, ch);
      if (ch != c.temporal_channels)
        throw Error(origin + ": temporal.channels " + arr(ch) + " must be [out_channels[2], out_channels[3], features, "
                    "features] = " + arr(c.temporal_channels));
      integer(t, "temporal", "num_attention_heads", 1, 1024, false, c.temporal_heads);
      integer(t, "temporal", "temporal_max_len", 1, 1 << 16, false, c.temporal_max_len);
      number(t, "temporal", "layer_norm_eps", c.temporal_layer_norm_eps);
      if (t.contains("group_norm") && t["group_norm"].is_object()) {
        integer(t["group_norm"], "temporal.group_norm", "num_groups", 1, 1 << 16, false, c.group_norm_groups);
        number(t["group_norm"], "temporal.group_norm", "eps", c.group_norm_eps);
      }
    }
    for (int ch : c.temporal_channels)
      if (ch % c.temporal_heads || ch % c.group_norm_groups)
        throw Error(origin + ": temporal channel count " + std::to_string(ch) + " is not a multiple of the " +
                    std::to_string(c.temporal_heads) + " temporal heads and the " + std::to_string(c.group_norm_groups) +
                    " GroupNorm groups");
    if (j.contains("inference") && j["inference"].is_object()) {
      const auto& inf = j["inference"];
      integer(inf, "inference", "infer_len", 1, 1 << 16, false, c.infer_len);
      integer(inf, "inference", "overlap", 0, c.infer_len - 1, false, c.overlap);
      integer(inf, "inference", "interp_len", 0, c.infer_len, false, c.interp_len);
      integer(inf, "inference", "input_size_default", 1, 1 << 16, false, c.input_size);
      if (inf.contains("keyframes")) {
        if (!inf["keyframes"].is_array()) throw Error(origin + ": inference.keyframes must be a list of frame positions");
        c.keyframes.clear();
        for (const auto& k : inf["keyframes"]) {
          if (!k.is_number_integer() || k.get<int>() < 0 || k.get<int>() >= c.infer_len)
            throw Error(origin + ": inference.keyframes entries must be frame positions in [0, infer_len)");
          c.keyframes.push_back(k.get<int>());
        }
      }
      if (inf.contains("metric") && inf["metric"].is_boolean()) c.metric = inf["metric"].get<bool>();
      if (inf.contains("normalize") && inf["normalize"].is_object())
        for (const char* key : {"mean", "std"}) {
          const auto& a = inf["normalize"][key];
          if (!a.is_array() || a.size() != 3) throw Error(origin + ": inference.normalize." + key + " must be 3 numbers");
          for (size_t i = 0; i < 3; ++i) (key[0] == 'm' ? c.mean : c.std)[i] = a[i].get<double>();
        }
    }
    if (c.temporal_max_len < c.infer_len)
      throw Error(origin + ": temporal.temporal_max_len " + std::to_string(c.temporal_max_len) +
                  " is shorter than inference.infer_len " + std::to_string(c.infer_len));
  } catch (const nlohmann::json::exception& e) {
    throw Error(origin + ": malformed Video-Depth-Anything config: " + e.what());
  }
  return c;
}

void check_vda_config_against(const VdaConfig& c, const std::map<std::string, Shape>& shapes,
                              const std::filesystem::path& checkpoint) {
  const Observed o = observe(shapes, checkpoint.string());
  auto seen = [](int v) { return v < 0 ? std::string("absent") : std::to_string(v); };
  auto mismatch = [&](const std::string& what, const std::string& config_value, const std::string& tensor_value) {
    throw Error(c.origin + " does not describe " + checkpoint.string() + ": " + what + " is " + config_value +
                " in the config but " + tensor_value + " in the tensors");
  };
  if (o.embed_dim != c.embed_dim) mismatch("the embed dim", std::to_string(c.embed_dim), std::to_string(o.embed_dim));
  if (o.depth != c.depth) mismatch("the encoder block count", std::to_string(c.depth), std::to_string(o.depth));
  if (o.features != c.features) mismatch("head.features", std::to_string(c.features), seen(o.features));
  if (o.out_channels != c.out_channels) mismatch("head.out_channels", arr(c.out_channels), arr(o.out_channels));
  if (o.pe_len >= 0 && o.pe_len != c.temporal_max_len)
    mismatch("temporal_max_len", std::to_string(c.temporal_max_len), std::to_string(o.pe_len) + " (pos_encoder.pe rows)");
}

VdaConfig resolve_vda_config(const std::filesystem::path& checkpoint, const std::map<std::string, Shape>& shapes) {
  // Another model's weights (a CogVideoX component, an image model) are named as such before any config beside
  // them is read as a VDA config or a missing tensor is reported.
  const bool encoder = shapes.count("pretrained.cls_token") || shapes.count("pretrained.patch_embed.proj.weight");
  const auto head = shapes.lower_bound("head.");
  if (!encoder || head == shapes.end() || head->first.rfind("head.", 0) != 0) {
    const std::string example = shapes.empty() ? std::string("it holds no tensors") : "its first tensor is " + shapes.begin()->first;
    throw Error(checkpoint.string() + ": not a Video-Depth-Anything checkpoint (no pretrained.cls_token / "
                "pretrained.patch_embed.* encoder or head.* tensors; " + example + "). Give --depth-model "
                "video_depth_anything_vits.pth (or _vitb, _vitl, metric_*), or a .safetensors made from one by "
                "dvs-weights convert");
  }
  const std::filesystem::path cfg = checkpoint.parent_path() / "config.json";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(cfg, ec)) return recognise_vda_size(shapes, checkpoint);
  VdaConfig c = vda_config_from_json(read_json_file(cfg), cfg.string());
  check_vda_config_against(c, shapes, checkpoint);
  return c;
}

}  // namespace dvs
