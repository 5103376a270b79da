#include "models/vda/vda_memory.hpp"

#include <algorithm>
#include <cstdio>
#include <map>
#include <vector>

#include "models/vda/vda_model.hpp"
#include "models/vda/vda_preprocess.hpp"
#include "models/random/vda_random.hpp"

namespace dvs {

VdaMemory plan_vda_memory(const VdaConfig& c, int64_t T, int64_t input_h, int64_t input_w, int64_t frame_h,
                          int64_t frame_w, int micro_batch, uint64_t alignment) {
  VdaMemory m;
  auto bytes = [&](int64_t elements) {
    const uint64_t b = uint64_t(elements) * 4;
    return (b + alignment - 1) / alignment * alignment;
  };
  auto note = [&](int64_t elements, const std::string& what) {
    if (bytes(elements) > m.largest_tensor) m.largest_tensor = bytes(elements), m.largest_what = what;
    return bytes(elements);
  };
  const std::vector<std::pair<std::string, Shape>> schema = vda_checkpoint_schema(c);
  std::map<std::string, Shape> shape_of(schema.begin(), schema.end());
  for (const auto& [name, shape] : schema) {
    if (name == "pretrained.pos_embed" || name == "pretrained.mask_token") continue;
    int64_t n = 1;
    for (int64_t d : shape) n *= d;
    // The transposed convs' bias is repeated over the k x k outputs of their Linear form (VdaModel::load).
    if (name == "head.resize_layers.0.bias" || name == "head.resize_layers.1.bias") {
      const Shape& k = shape_of.at(name.substr(0, name.size() - 4) + "weight");
      n *= k[2] * k[3];
    }
    if (VdaModel::packs_as_conv(name, shape)) n = shape_numel(ops::packed_conv_weights_shape(shape));  // Cin to 8
    if (name.find("ff.net.0.proj") != std::string::npos) {  // split into two halves
      m.weights += 2 * bytes(n / 2);
      continue;
    }
    m.weights += note(n, name);
  }
  const int64_t ps = c.patch_size, h = input_h / ps, w = input_w / ps, hw = h * w, N = 1 + hw, D = c.embed_dim;
  const int64_t P1 = 16 * hw, P2 = 4 * hw, P3 = hw, P4 = ((h + 1) / 2) * ((w + 1) / 2), Pf = input_h * input_w;
  const auto& oc = c.out_channels;
  const int64_t F = c.features, F2 = c.output_conv1_out, chunk = micro_batch > 0 ? std::min<int64_t>(micro_batch, T) : T;
  const uint64_t input = note(T * 3 * Pf, "window input"), pos = bytes(N * D), out = note(T * Pf, "window disparity");
  struct Phase {
    std::string name;
    uint64_t bytes;
  };
  std::vector<Phase> phases;
  // Encoder, VdaModel::kEncoderChunkFrames frames at a time: the chunk's patches, tokens and block temporaries
  // (norm, qkv, attention, MLP hidden), and the four taps of the whole window.
  const int64_t e = std::min<int64_t>(VdaModel::kEncoderChunkFrames, T);
  const uint64_t taps = 4 * note(T * hw * D, "encoder tap");
  phases.push_back({"encoder", input + pos + bytes(e * hw * D) + note(e * N * D, "encoder tokens") * 4 +
                                   note(e * N * 3 * D, "encoder qkv") + note(e * N * c.mlp_hidden_dim, "encoder MLP hidden") +
                                   taps + bytes(2 * N * D + 1024)});  // + the attention's K/V workspace on CPUs
  // A temporal module on a [T, C, P] map: its input, the group norm (or the output) and the position-major
  // tokens, plus one chunk of positions' working set (hidden, norm, q, k, v, context: C each; the GEGLU halves:
  // 4C each), chunked as VdaModel::temporal does.
  auto temporal = [&](int64_t C, int64_t P, const char* what) {
    const int64_t per_position = T * C * 4 * 14;
    const int64_t n = std::clamp<int64_t>(VdaModel::kTemporalChunkBytes / per_position, 1, P);
    return 3 * bytes(T * C * P) + 6 * bytes(n * T * C) + 2 * note(n * T * 4 * C, what);
  };
  const uint64_t layers = bytes(T * oc[0] * P1) + bytes(T * oc[1] * P2) + bytes(T * oc[2] * P3) + bytes(T * oc[3] * P4);
  note(T * oc[0] * P1, "head layer1");
  // Reassembly and temporal modules 0-1: taps, the four reassembled maps, one module's working set.
  phases.push_back({"head (reassemble, temporal 0-1)",
                    input + taps + layers + bytes(T * hw * oc[0] * 16) +
                        std::max(temporal(oc[2], P3, "temporal module 0 GEGLU"), temporal(oc[3], P4, "temporal module 1 GEGLU"))});
  // Fusion of the coarse levels and temporal modules 2-3: the F-channel maps of every level, a fusion block's
  // temporaries (3 residual-unit maps, the sum, the resized map), one module's working set.
  const uint64_t rn = bytes(T * F * P1) + bytes(T * F * P2) + bytes(T * F * P3) + bytes(T * F * P4);
  note(T * F * P1, "head layer1_rn");
  phases.push_back({"head (fusion 4-3, temporal 2-3)", input + rn + 2 * bytes(T * F * P2) + 5 * bytes(T * F * P2) +
                                                           std::max(temporal(F, P3, "temporal module 2 GEGLU"),
                                                                    temporal(F, P2, "temporal module 3 GEGLU"))});
  // The full-resolution tail, `chunk` frames at a time: fusion 2 and 1 (residual units, resize to 2x), output
  // convolutions, the upsampled map and the 32-channel hidden map; the window's disparity is being filled.
  const uint64_t tail = 6 * bytes(chunk * F * P1) + 3 * bytes(chunk * F * 4 * P1) + bytes(chunk * F2 * 4 * P1) +
                        note(chunk * F2 * Pf, "head output resize (one chunk)") +
                        note(chunk * 32 * Pf, "head output_conv2 hidden (one chunk)") + bytes(chunk * Pf);
  phases.push_back({"head (full-resolution tail)", input + rn + bytes(T * F * P2) + out + tail});
  // The window resized to the frame size (and downloaded).
  phases.push_back({"upsampling to the frame size", input + out + note(T * frame_h * frame_w, "window at the frame size")});
  for (const auto& p : phases)
    if (p.bytes > m.activations) m.activations = p.bytes, m.peak_phase = p.name;
  return m;
}

namespace {

std::string mib(uint64_t b) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f MiB", double(b) / double(1ull << 20));
  return buf;
}

}  // namespace

std::string vda_fit_problem(const VdaConfig& c, int64_t frame_h, int64_t frame_w, int input_size, uint64_t alloc,
                            std::optional<uint64_t> budget, uint64_t alignment, const std::string& limit_source,
                            const std::string& option) {
  auto problem = [&](int size) -> std::string {
    const VdaInputSize in = vda_input_size(frame_h, frame_w, size, c.patch_size);
    const VdaMemory m = plan_vda_memory(c, c.infer_len, in.height, in.width, frame_h, frame_w, VdaModel::kHeadMicroBatch, alignment);
    if (alloc && m.largest_tensor > alloc)
      return "the depth estimate's " + m.largest_what + " (" + mib(m.largest_tensor) + " at network input " +
             std::to_string(in.height) + "x" + std::to_string(in.width) + ") exceeds maxMemoryAllocationSize " + mib(alloc) +
             (limit_source.empty() ? std::string() : " of " + limit_source);
    if (budget && m.total() > *budget)
      return "the depth estimate needs " + mib(m.total()) + " (weights " + mib(m.weights) + " + its largest phase, " +
             m.peak_phase + "), over the device memory " + mib(*budget);
    return "";
  };
  std::string p = problem(input_size);
  if (p.empty()) return p;
  for (int size = (input_size - 1) / 14 * 14; size >= 14; size -= 14)
    if (problem(size).empty())
      return p + "; a smaller network input fits: " + option + " " + std::to_string(size) + " (or a smaller video)";
  return p + "; no " + option + " fits (give --depth with an estimate made elsewhere)";
}

}  // namespace dvs
