// The architecture of a Video-Depth-Anything checkpoint: recognised from its tensors for the released sizes
// (vits / vitb / vitl, relative or metric: same keys), or read from a `config.json` beside the checkpoint in the
// conformance pack's schema ("vda-conformance-config/1", see tests/golden/vda-A/model/config.json), which
// describes any other size and wins when present (it is still checked against the tensors).
//
// Upstream hard-codes its sizes; the table here is the pack README's: embed dim, depth, heads and tapped
// layers, DPT features and out_channels per size. Everything else is the same for every size.
#pragma once
#include <array>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/host_tensor.hpp"

namespace dvs {

struct VdaConfig {
  std::string name;    // "vits", "vitb", "vitl", or the config's encoder.name
  std::string origin;  // where it came from: "recognised from the tensors of FILE" or the config.json path

  // DINOv2 encoder
  int embed_dim = 0, depth = 0, num_heads = 0, head_dim = 0, mlp_hidden_dim = 0;
  int patch_size = 14, pos_embed_grid = 37;
  float vit_layer_norm_eps = 1e-6f;
  std::array<int, 4> taps{};  // 0-based block indices whose outputs feed the head (intermediate_layer_idx)

  // DPT head
  int features = 0;
  std::array<int, 4> out_channels{};
  int output_conv1_out = 0;  // features / 2

  // Temporal modules (on layer_3, layer_4, path_4, path_3)
  std::array<int, 4> temporal_channels{};  // out_channels[2], out_channels[3], features, features
  int temporal_heads = 8, temporal_max_len = 32, group_norm_groups = 32;
  float group_norm_eps = 1e-6f, temporal_layer_norm_eps = 1e-5f;

  // Long-video inference
  int infer_len = 32, overlap = 10, interp_len = 8, input_size = 518;
  std::vector<int> keyframes{0, 12, 24, 25, 26, 27, 28, 29, 30, 31};
  std::array<double, 3> mean{0.485, 0.456, 0.406}, std{0.229, 0.224, 0.225};  // Python floats: numpy normalises in double
  bool metric = false;  // metric checkpoints skip the scale/shift alignment
};

// A released size by name ("vits", "vitb", "vitl"); dvs::Error otherwise.
VdaConfig released_vda_config(const std::string& name);

// The released size whose embed dim / depth / features match, else a dvs::Error telling the user to add a
// config.json. `shapes` maps tensor names to shapes (only shapes are needed); `file` names the checkpoint.
// metric is set when the file name starts with "metric_" (the released metric checkpoints' names).
VdaConfig recognise_vda_size(const std::map<std::string, Shape>& shapes, const std::filesystem::path& file);

// A config in the pack's schema; `origin` names it in errors. Checks ranges and internal consistency.
VdaConfig vda_config_from_json(const nlohmann::json& j, const std::string& origin);

// config.json beside `checkpoint` when present (checked against the tensors), else recognise_vda_size.
VdaConfig resolve_vda_config(const std::filesystem::path& checkpoint, const std::map<std::string, Shape>& shapes);

// Throws when the tensors cannot belong to `c` (embed dim, block count, features, out_channels).
void check_vda_config_against(const VdaConfig& c, const std::map<std::string, Shape>& shapes,
                              const std::filesystem::path& checkpoint);

}  // namespace dvs
