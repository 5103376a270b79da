// The vda-A pack's checkpoint through the .pth reader: key list and shapes from cases.json, values checked
// against independent sources (the sinusoidal formula, the pack's npy files, a plain C++ patch-embedding
// convolution), size recognition and config.json, `dvs-weights inspect/convert`, and fuzzing with truncated and
// bit-flipped copies of the real file. Sizes and keys come from the pack (DVS_VDA_GOLDEN_DIR), never from code.
#include <gtest/gtest.h>
#include <zip.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "dvs/error.hpp"
#include "io/npy.hpp"
#include "io/pickle_state_dict.hpp"
#include "io/pth_file.hpp"
#include "io/safetensors.hpp"
#include "spec/vda_config.hpp"
#include "support/files.hpp"
#include "support/process.hpp"
#include "support/vda_pack.hpp"

namespace fs = std::filesystem;
using dvs::test::TempDir;
using dvs::test::vda_cases;
using dvs::test::vda_checkpoint_path;
using dvs::test::vda_golden_path;
using dvs::test::vda_model_config;
using nlohmann::json;

namespace {

std::vector<float> floats(const std::vector<uint8_t>& b) {
  std::vector<float> v(b.size() / 4);
  std::memcpy(v.data(), b.data(), v.size() * 4);
  return v;
}

std::map<std::string, dvs::Shape> shapes_of(const dvs::PthFile& f) {
  std::map<std::string, dvs::Shape> m;
  for (const auto& t : f.tensors()) m[t.name] = t.shape;
  return m;
}

using dvs::test::error_of;

// The bytes of the archive's */data.pkl record, read with libzip independently of the reader under test.
std::string pickle_of(const fs::path& p) {
  int err = 0;
  zip_t* za = zip_open(p.c_str(), ZIP_RDONLY, &err);
  if (!za) throw std::runtime_error("cannot open " + p.string());
  std::string out;
  for (zip_int64_t i = 0; i < zip_get_num_entries(za, 0); ++i) {
    const std::string name = zip_get_name(za, zip_uint64_t(i), 0);
    if (name.size() < 9 || name.compare(name.size() - 9, 9, "/data.pkl") != 0) continue;
    zip_stat_t st;
    zip_stat_index(za, zip_uint64_t(i), 0, &st);
    out.resize(st.size);
    zip_file_t* f = zip_fopen_index(za, zip_uint64_t(i), 0);
    zip_fread(f, out.data(), out.size());
    zip_fclose(f);
  }
  zip_discard(za);
  return out;
}

struct Snapshot {
  std::vector<std::string> names;
  std::vector<dvs::Shape> shapes;
  std::vector<std::vector<uint8_t>> bytes;
};

Snapshot snapshot(const fs::path& p) {
  const dvs::PthFile f = dvs::PthFile::open(p);
  Snapshot s;
  for (const auto& t : f.tensors()) {
    s.names.push_back(t.name);
    s.shapes.push_back(t.shape);
    s.bytes.push_back(f.read_bytes(t));
  }
  return s;
}

}  // namespace

TEST(PthVdaPack, KeysShapesAndBytesMatchCasesJson) {
  const auto& ck = vda_cases().at("checkpoint");
  const dvs::PthFile f = dvs::PthFile::open(vda_checkpoint_path());
  const auto& keys = ck.at("keys");
  ASSERT_EQ(f.tensors().size(), keys.size());
  EXPECT_EQ(f.tensors().size(), ck.at("n_tensors").get<size_t>());
  for (size_t i = 0; i < keys.size(); ++i) {
    const auto& t = f.tensors()[i];
    EXPECT_EQ(t.name, keys[i].at(0).get<std::string>()) << "tensor " << i << " (state_dict order)";
    EXPECT_EQ(t.shape, keys[i].at(1).get<dvs::Shape>()) << t.name;
    EXPECT_EQ(t.dtype_name, "F32") << t.name;
    if (ck.at("all_contiguous").get<bool>()) {
      EXPECT_TRUE(t.contiguous) << t.name;
    }
  }
  EXPECT_EQ(ck.at("dtypes"), json::array({"torch.float32"}));
  EXPECT_EQ(f.total_bytes(), ck.at("tensor_bytes").get<uint64_t>());
  uint64_t read = 0;
  for (const auto& t : f.tensors()) read += f.read_bytes(t).size();
  EXPECT_EQ(read, ck.at("tensor_bytes").get<uint64_t>());
  EXPECT_FALSE(f.record_prefix().empty());
  EXPECT_EQ(f.unwrapped(), "") << "the released layout has no wrapper";
  EXPECT_FALSE(f.stripped_module_prefix());
}

// The temporal pos_encoder.pe buffers are stored, not learned: pe[t, 2i] = sin(t * 10000^(-2i/C)),
// pe[t, 2i+1] = cos(same) (pack README). Both the layout and the values must come out of the reader intact.
TEST(PthVdaPack, TemporalPositionBuffersAreTheSinusoidalTable) {
  const dvs::PthFile f = dvs::PthFile::open(vda_checkpoint_path());
  int checked = 0;
  for (const auto& t : f.tensors()) {
    if (t.name.find("pos_encoder.pe") == std::string::npos) continue;
    ASSERT_EQ(t.shape.size(), 3u) << t.name;
    const int64_t L = t.shape[1], C = t.shape[2];
    const auto v = floats(f.read_bytes(t));
    double worst = 0;
    for (int64_t pos = 0; pos < L; ++pos)
      for (int64_t c = 0; c < C; ++c) {
        const double freq = std::pow(10000.0, -double(c - c % 2) / double(C));
        const double want = c % 2 ? std::cos(double(pos) * freq) : std::sin(double(pos) * freq);
        worst = std::max(worst, std::abs(double(v[size_t(pos * C + c)]) - want));
      }
    EXPECT_LT(worst, 1e-5) << t.name;  // torch builds it in float32: |arg| <= 31 -> ~4e-6
    ++checked;
  }
  EXPECT_EQ(checked, 8) << "pack README: 4 temporal modules x 2 attention blocks";
  // The table grows along t: a reader that transposed [L, C] would put pe[1, 0] = sin(1) elsewhere.
  const auto pe = f.load("head.motion_modules.0.temporal_transformer.transformer_blocks.0.attention_blocks.0.pos_encoder.pe");
  EXPECT_NEAR(pe.to_f32()[size_t(pe.shape[2])], std::sin(1.0), 1e-6);
}

TEST(PthVdaPack, PosEmbedEqualsThePackParam) {
  const dvs::PthFile f = dvs::PthFile::open(vda_checkpoint_path());
  const dvs::HostTensor ours = f.load("pretrained.pos_embed");
  const dvs::HostTensor golden = dvs::read_npy(vda_golden_path() / "pos_embed" / "param.npy");
  EXPECT_EQ(ours.shape, golden.shape);
  EXPECT_EQ(ours.data, golden.data) << "bit-identical: the npy is the same parameter";
}

// encoder/patch_embed.npy = Conv2d(3, D, k=p, s=p)(window/input) flattened row-major over patches: recomputed here
// in plain C++ from the checkpoint's patch_embed weight [D, 3, p, p] and bias, which checks their layout.
TEST(PthVdaPack, PatchEmbeddingFromTheCheckpointMatchesThePack) {
  const dvs::PthFile f = dvs::PthFile::open(vda_checkpoint_path());
  const dvs::HostTensor w = f.load("pretrained.patch_embed.proj.weight");
  const auto wv = w.to_f32(), bv = f.load("pretrained.patch_embed.proj.bias").to_f32();
  const dvs::HostTensor in = dvs::read_npy(vda_golden_path() / "window" / "input.npy");       // [B,T,3,H,W]
  const dvs::HostTensor golden = dvs::read_npy(vda_golden_path() / "encoder" / "patch_embed.npy");  // [BT, h*w, D]
  const auto x = in.to_f32(), g = golden.to_f32();
  const int64_t D = w.shape[0], Cin = w.shape[1], P = w.shape[2];
  ASSERT_EQ(P, vda_model_config().at("encoder").at("patch_size").get<int64_t>());
  const int64_t BT = in.shape[0] * in.shape[1], H = in.shape[3], W = in.shape[4], h = H / P, wp = W / P;
  ASSERT_EQ(golden.shape, (dvs::Shape{BT, h * wp, D}));
  const auto& tol = dvs::test::vda_case("encoder").at("tolerance");
  const double atol = tol.at("atol").get<double>(), rtol = tol.at("rtol").get<double>();
  size_t bad = 0;
  for (int64_t n = 0; n < BT; ++n)
    for (int64_t py = 0; py < h; ++py)
      for (int64_t px = 0; px < wp; ++px)
        for (int64_t d = 0; d < D; ++d) {
          double acc = bv[size_t(d)];
          for (int64_t c = 0; c < Cin; ++c)
            for (int64_t ky = 0; ky < P; ++ky)
              for (int64_t kx = 0; kx < P; ++kx)
                acc += double(wv[size_t(((d * Cin + c) * P + ky) * P + kx)]) *
                       double(x[size_t(((n * Cin + c) * H + py * P + ky) * W + px * P + kx)]);
          const double want = g[size_t((n * h * wp + py * wp + px) * D + d)];
          if (std::abs(acc - want) > atol + rtol * std::abs(want)) ++bad;
        }
  EXPECT_EQ(bad, 0u);
}

// Released sizes are recognised from shapes alone; the expected architecture is the pack config's table.
TEST(PthVdaConfig, RecognisesEveryReleasedSizeFromShapes) {
  const auto& released = vda_model_config().at("released_sizes");
  ASSERT_EQ(released.size(), 3u);
  for (const auto& [size, r] : released.items()) {
    SCOPED_TRACE(size);
    const auto& enc = r.at("encoder");
    const auto& head = r.at("head");
    const int64_t D = enc.at("embed_dim"), depth = enc.at("depth");
    const auto oc = head.at("out_channels").get<std::vector<int64_t>>();
    const auto tc = r.at("temporal").at("channels").get<std::vector<int64_t>>();
    std::map<std::string, dvs::Shape> m;
    m["pretrained.cls_token"] = {1, 1, D};
    m["pretrained.patch_embed.proj.weight"] = {D, 3, 14, 14};
    for (int64_t b = 0; b < depth; ++b) m["pretrained.blocks." + std::to_string(b) + ".norm1.weight"] = {D};
    for (int i = 0; i < 4; ++i) m["head.projects." + std::to_string(i) + ".weight"] = {oc[size_t(i)], D, 1, 1};
    m["head.scratch.layer1_rn.weight"] = {head.at("features").get<int64_t>(), oc[0], 3, 3};
    m["head.motion_modules.0.temporal_transformer.transformer_blocks.0.attention_blocks.0.pos_encoder.pe"] = {1, 32, tc[0]};

    const dvs::VdaConfig c = dvs::recognise_vda_size(m, r.at("checkpoint").get<std::string>());
    EXPECT_EQ(c.name, enc.at("name").get<std::string>());
    EXPECT_EQ(c.embed_dim, D);
    EXPECT_EQ(c.depth, depth);
    EXPECT_EQ(c.num_heads, enc.at("num_heads").get<int>());
    EXPECT_EQ(c.head_dim, enc.at("head_dim").get<int>());
    EXPECT_EQ(c.mlp_hidden_dim, enc.at("mlp_hidden_dim").get<int>());
    EXPECT_EQ(std::vector<int>(c.taps.begin(), c.taps.end()), enc.at("intermediate_layer_idx").get<std::vector<int>>());
    EXPECT_EQ(c.features, head.at("features").get<int>());
    EXPECT_EQ(c.output_conv1_out, head.at("output_conv1_out").get<int>());
    EXPECT_EQ(std::vector<int64_t>(c.out_channels.begin(), c.out_channels.end()), oc);
    EXPECT_EQ(std::vector<int64_t>(c.temporal_channels.begin(), c.temporal_channels.end()), tc);
    for (int i = 0; i < 4; ++i)
      EXPECT_EQ(c.temporal_channels[size_t(i)] / c.temporal_heads, r.at("temporal").at("head_dims")[size_t(i)].get<int>());
    EXPECT_FALSE(c.metric);
    EXPECT_TRUE(dvs::recognise_vda_size(m, r.at("metric_checkpoint").get<std::string>()).metric);

    // One block fewer is no released size.
    auto fewer = m;
    fewer.erase("pretrained.blocks." + std::to_string(depth - 1) + ".norm1.weight");
    EXPECT_NE(error_of([&] { dvs::recognise_vda_size(fewer, "x.pth"); }).find("config.json"), std::string::npos);
    // The released encoder with another head is not a released size either.
    auto other_head = m;
    other_head["head.scratch.layer1_rn.weight"][0] += 1;
    EXPECT_NE(error_of([&] { dvs::recognise_vda_size(other_head, "x.pth"); }).find("DPT head"), std::string::npos);
  }
}

TEST(PthVdaConfig, PackConfigBesideTheCheckpointWins) {
  const fs::path ckpt = vda_checkpoint_path();
  const dvs::PthFile f = dvs::PthFile::open(ckpt);
  const dvs::VdaConfig c = dvs::resolve_vda_config(ckpt, shapes_of(f));
  const auto& enc = vda_model_config().at("encoder");
  const auto& head = vda_model_config().at("head");
  const auto& temporal = vda_model_config().at("temporal");
  const auto& inference = vda_model_config().at("inference");
  EXPECT_EQ(c.name, enc.at("name").get<std::string>());
  EXPECT_NE(c.origin.find("config.json"), std::string::npos);
  EXPECT_EQ(c.embed_dim, enc.at("embed_dim").get<int>());
  EXPECT_EQ(c.depth, enc.at("depth").get<int>());
  EXPECT_EQ(c.num_heads, enc.at("num_heads").get<int>());
  EXPECT_EQ(c.head_dim, enc.at("head_dim").get<int>());
  EXPECT_EQ(c.mlp_hidden_dim, enc.at("mlp_hidden_dim").get<int>());
  EXPECT_EQ(std::vector<int>(c.taps.begin(), c.taps.end()), enc.at("intermediate_layer_idx").get<std::vector<int>>());
  EXPECT_EQ(c.features, head.at("features").get<int>());
  EXPECT_EQ(std::vector<int>(c.out_channels.begin(), c.out_channels.end()), head.at("out_channels").get<std::vector<int>>());
  EXPECT_EQ(c.output_conv1_out, head.at("output_conv1_out").get<int>());
  EXPECT_EQ(std::vector<int>(c.temporal_channels.begin(), c.temporal_channels.end()),
            temporal.at("channels").get<std::vector<int>>());
  EXPECT_EQ(c.temporal_heads, temporal.at("num_attention_heads").get<int>());
  EXPECT_EQ(c.temporal_max_len, temporal.at("temporal_max_len").get<int>());
  EXPECT_EQ(c.group_norm_groups, temporal.at("group_norm").at("num_groups").get<int>());
  EXPECT_FLOAT_EQ(c.group_norm_eps, temporal.at("group_norm").at("eps").get<float>());
  EXPECT_FLOAT_EQ(c.temporal_layer_norm_eps, temporal.at("layer_norm_eps").get<float>());
  EXPECT_EQ(c.infer_len, inference.at("infer_len").get<int>());
  EXPECT_EQ(c.overlap, inference.at("overlap").get<int>());
  EXPECT_EQ(c.interp_len, inference.at("interp_len").get<int>());
  EXPECT_EQ(c.keyframes, inference.at("keyframes").get<std::vector<int>>());
  EXPECT_EQ(c.metric, inference.at("metric").get<bool>());
  for (size_t i = 0; i < 3; ++i) {
    EXPECT_FLOAT_EQ(c.mean[i], inference.at("normalize").at("mean")[i].get<float>());
    EXPECT_FLOAT_EQ(c.std[i], inference.at("normalize").at("std")[i].get<float>());
  }

  // The same shapes without a config.json beside them: an unknown size, and the error says what to do.
  TempDir dir;
  fs::copy_file(ckpt, dir / "model.pth");
  const std::string e = error_of([&] { dvs::resolve_vda_config(dir / "model.pth", shapes_of(f)); });
  EXPECT_NE(e.find((dir / "model.pth").string()), std::string::npos) << e;
  EXPECT_NE(e.find("embed dim " + std::to_string(c.embed_dim)), std::string::npos) << e;
  EXPECT_NE(e.find("put a config.json beside the checkpoint"), std::string::npos) << e;

  // A config.json that does not fit the tensors is refused, naming both.
  json wrong = vda_model_config();
  wrong["encoder"]["depth"] = c.depth + 1;
  wrong["encoder"]["intermediate_layer_idx"] = enc.at("intermediate_layer_idx");
  dvs::test::write_text(dir / "config.json", wrong.dump());
  const std::string e2 = error_of([&] { dvs::resolve_vda_config(dir / "model.pth", shapes_of(f)); });
  EXPECT_NE(e2.find("does not describe"), std::string::npos) << e2;
  EXPECT_NE(e2.find("block count"), std::string::npos) << e2;
}

// A config.json beside a released-size checkpoint overrides the table (e.g. a fine-tune with other heads).
TEST(PthVdaConfig, ConfigOverridesRecognition) {
  const auto& vits = vda_model_config().at("released_sizes").at("vits");
  json cfg = vda_model_config();
  for (const auto& [k, v] : vits.at("encoder").items()) cfg["encoder"][k] = v;
  for (const auto& [k, v] : vits.at("head").items()) cfg["head"][k] = v;
  for (const auto& [k, v] : vits.at("temporal").items()) cfg["temporal"][k] = v;
  cfg["encoder"]["num_heads"] = 12;
  cfg["encoder"]["head_dim"] = 32;
  cfg["encoder"]["name"] = "vits-12-heads";
  TempDir dir;
  dvs::test::write_text(dir / "config.json", cfg.dump());
  std::map<std::string, dvs::Shape> m;
  const int64_t D = vits.at("encoder").at("embed_dim");
  const auto oc = vits.at("head").at("out_channels").get<std::vector<int64_t>>();
  m["pretrained.cls_token"] = {1, 1, D};
  for (int b = 0; b < vits.at("encoder").at("depth").get<int>(); ++b) m["pretrained.blocks." + std::to_string(b) + ".ls1.gamma"] = {D};
  for (int i = 0; i < 4; ++i) m["head.projects." + std::to_string(i) + ".weight"] = {oc[size_t(i)], D, 1, 1};
  m["head.scratch.layer1_rn.weight"] = {vits.at("head").at("features").get<int64_t>(), oc[0], 3, 3};
  const dvs::VdaConfig c = dvs::resolve_vda_config(dir / "video_depth_anything_vits.pth", m);
  EXPECT_EQ(c.name, "vits-12-heads");
  EXPECT_EQ(c.num_heads, 12);
  EXPECT_EQ(c.head_dim, 32);
  fs::remove(dir / "config.json");
  EXPECT_EQ(dvs::resolve_vda_config(dir / "video_depth_anything_vits.pth", m).num_heads,
            vits.at("encoder").at("num_heads").get<int>());
}

TEST(PthVdaConfig, InvalidConfigsAreRefused) {
  auto err = [](const std::function<void(json&)>& edit) {
    json j = vda_model_config();
    edit(j);
    return error_of([&] { dvs::vda_config_from_json(j, "cfg.json"); });
  };
  EXPECT_EQ(err([](json&) {}), "");
  EXPECT_NE(err([](json& j) { j["encoder"]["intermediate_layer_idx"][3] = j["encoder"]["depth"]; }).find("intermediate_layer_idx[3]"),
            std::string::npos);
  EXPECT_NE(err([](json& j) { j["encoder"]["num_heads"] = 3; }).find("not a multiple of num_heads"), std::string::npos);
  EXPECT_NE(err([](json& j) { j["encoder"].erase("embed_dim"); }).find("encoder.embed_dim is missing"), std::string::npos);
  EXPECT_NE(err([](json& j) { j["head"]["out_channels"] = json::array({1, 2}); }).find("list of 4"), std::string::npos);
  EXPECT_NE(err([](json& j) { j["temporal"]["channels"][0] = 64; }).find("temporal.channels"), std::string::npos);
  EXPECT_NE(err([](json& j) { j.erase("head"); }).find("no \"head\""), std::string::npos);
  EXPECT_NE(err([](json& j) { j["encoder"]["depth"] = "five"; }).find("encoder.depth"), std::string::npos);
}

TEST(PthVdaCli, InspectListsAndConvertRoundTripsByteExact) {
  const fs::path ckpt = vda_checkpoint_path();
  const auto& ck = vda_cases().at("checkpoint");
  const auto r = dvs::test::run_command(dvs::test::program("dvs-weights") + " inspect " + ckpt.string() + " 2>&1");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find(std::to_string(ck.at("n_tensors").get<int>()) + " tensors, " +
                          std::to_string(ck.at("tensor_bytes").get<uint64_t>()) + " bytes"),
            std::string::npos)
      << r.output;
  const auto& first = ck.at("keys")[0];
  EXPECT_NE(r.output.find(first.at(0).get<std::string>()), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("Video-Depth-Anything " + vda_model_config().at("encoder").at("name").get<std::string>()),
            std::string::npos)
      << r.output;

  TempDir dir;
  const fs::path out = dir / "model.safetensors";
  const auto c = dvs::test::run_command(dvs::test::program("dvs-weights") + " convert " + ckpt.string() + " " +
                                        out.string() + " 2>&1");
  ASSERT_EQ(c.exit_code, 0) << c.output;
  const dvs::PthFile pth = dvs::PthFile::open(ckpt);
  const dvs::SafetensorsFile st = dvs::SafetensorsFile::open(out);
  ASSERT_EQ(st.tensors().size(), pth.tensors().size());
  for (const auto& t : pth.tensors()) {
    const dvs::TensorInfo* s = st.find(t.name);
    ASSERT_TRUE(s) << t.name;
    EXPECT_EQ(s->dtype_name, t.dtype_name) << t.name;
    EXPECT_EQ(s->shape, t.shape) << t.name;
    const auto want = pth.read_bytes(t);
    const auto got = st.bytes(*s);
    ASSERT_EQ(got.size(), want.size()) << t.name;
    EXPECT_EQ(std::memcmp(got.data(), want.data(), want.size()), 0) << t.name;
  }

  const auto again = dvs::test::run_command(dvs::test::program("dvs-weights") + " convert " + ckpt.string() + " " +
                                            out.string() + " 2>&1");
  EXPECT_EQ(again.exit_code, 1);
  EXPECT_NE(again.output.find("already exists"), std::string::npos) << again.output;

  const fs::path bad = dir / "bad.pth";
  dvs::test::write_text(bad, "not a checkpoint");
  const auto b = dvs::test::run_command(dvs::test::program("dvs-weights") + " inspect " + bad.string() + " 2>&1");
  EXPECT_EQ(b.exit_code, 1);
  EXPECT_NE(b.output.find(bad.string() + ": not a readable PyTorch checkpoint"), std::string::npos) << b.output;
  const auto u = dvs::test::run_command(dvs::test::program("dvs-weights") + " convert " + ckpt.string() + " 2>&1");
  EXPECT_EQ(u.exit_code, 2) << u.output;
}

// The real checkpoint, truncated or with one byte flipped at many positions: every outcome is a clean dvs::Error
// or the exact original tensors, never a crash, a hang or another exception.
TEST(PthVdaFuzz, TruncatedAndFlippedCheckpointFailCleanly) {
  const fs::path ckpt = vda_checkpoint_path();
  const std::string original = dvs::test::read_text(ckpt);
  const Snapshot ref = snapshot(ckpt);
  const size_t n = original.size();
  const size_t pickle_end = pickle_of(ckpt).size() + 200;  // data.pkl is the archive's first record
  std::vector<size_t> cuts{0, 1, 4, 22, 30, 100, n - 1, n - 2, n - 22, n - 23};
  for (size_t i = 1; i < 48; ++i) cuts.push_back(n * i / 48);
  std::vector<size_t> flips;
  for (size_t p = 0; p < pickle_end; p += 211) flips.push_back(p);               // local header + pickle
  for (size_t i = 0; i < 120; ++i) flips.push_back(pickle_end + (n - pickle_end) * i / 120);  // storages
  for (size_t p = n - 1; p > n - 4000 && p > 0; p -= 37) flips.push_back(p);     // central directory, end record

  TempDir dir;
  const fs::path p = dir / "fuzz.pth";
  int errors = 0, parsed = 0;
  auto check = [&](const std::string& bytes, const std::string& what) {
    dvs::test::write_text(p, bytes);
    try {
      const Snapshot s = snapshot(p);
      ++parsed;
      EXPECT_EQ(s.names, ref.names) << what;
      EXPECT_EQ(s.shapes, ref.shapes) << what;
      EXPECT_TRUE(s.bytes == ref.bytes) << what << ": parsed without error but with other values";
    } catch (const dvs::Error& e) {
      ++errors;
      EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << what << ": " << e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << what << ": not a dvs::Error: " << e.what();
    }
  };
  for (size_t c : cuts) check(original.substr(0, c), "truncated to " + std::to_string(c) + " bytes");
  std::mt19937 rng(1);
  for (size_t f : flips) {
    std::string b = original;
    b[f] = char(uint8_t(b[f]) ^ uint8_t(1u << (rng() % 8)));
    check(b, "byte " + std::to_string(f) + " flipped");
  }
  std::cout << "[ fuzz ] " << cuts.size() + flips.size() << " corrupt copies: " << errors << " errors, " << parsed
            << " parsed identically\n";
  EXPECT_GT(errors, int(cuts.size()) - 3);
}

// Mutated pickles with intact CRCs (re-zipped with the original storages), so that what the pickle claims about
// storages, offsets and shapes reaches the bounds checks: a clean dvs::Error, or tensors that read back at the
// size they claim.
TEST(PthVdaFuzz, RezippedMutatedPicklesHitTheBoundsChecksCleanly) {
  const fs::path ckpt = vda_checkpoint_path();
  std::vector<std::pair<std::string, std::string>> records;
  {
    int err = 0;
    zip_t* za = zip_open(ckpt.c_str(), ZIP_RDONLY, &err);
    ASSERT_NE(za, nullptr);
    for (zip_int64_t i = 0; i < zip_get_num_entries(za, 0); ++i) {
      zip_stat_t st;
      zip_stat_index(za, zip_uint64_t(i), 0, &st);
      std::string data(st.size, '\0');
      zip_file_t* f = zip_fopen_index(za, zip_uint64_t(i), 0);
      zip_fread(f, data.data(), data.size());
      zip_fclose(f);
      records.emplace_back(zip_get_name(za, zip_uint64_t(i), 0), std::move(data));
    }
    zip_discard(za);
  }
  size_t pkl = records.size();
  for (size_t i = 0; i < records.size(); ++i)
    if (records[i].first.size() > 9 && records[i].first.compare(records[i].first.size() - 9, 9, "/data.pkl") == 0) pkl = i;
  ASSERT_LT(pkl, records.size());
  const std::string original = records[pkl].second;
  TempDir dir;
  const fs::path p = dir / "m.pth";
  std::mt19937 rng(3);
  int errors = 0, parsed = 0;
  for (int iter = 0; iter < 120; ++iter) {
    std::string b = original;
    // Small integers (sizes, strides, offsets, storage sizes) are the BININT1/BININT2 arguments: change one.
    size_t pos = rng() % b.size();
    while (pos + 1 < b.size() && b[pos] != 'K' && b[pos] != 'M') ++pos;
    if (pos + 1 < b.size()) b[pos + 1] = char(rng() % 256);
    records[pkl].second = b;
    int err = 0;
    zip_t* za = zip_open(p.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &err);
    ASSERT_NE(za, nullptr);
    for (const auto& [name, data] : records) {
      const zip_int64_t idx = zip_file_add(za, name.c_str(), zip_source_buffer(za, data.data(), data.size(), 0), 0);
      zip_set_file_compression(za, zip_uint64_t(idx), ZIP_CM_STORE, 0);
    }
    ASSERT_EQ(zip_close(za), 0);
    try {
      const dvs::PthFile f = dvs::PthFile::open(p);
      for (const auto& t : f.tensors()) EXPECT_EQ(f.read_bytes(t).size(), t.nbytes()) << t.name;
      ++parsed;
    } catch (const dvs::Error& e) {
      ++errors;
      EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << "byte " << pos + 1 << ": not a dvs::Error: " << e.what();
    }
  }
  std::cout << "[ fuzz ] re-zipped mutated pickles: " << errors << " errors, " << parsed << " parsed\n";
  EXPECT_GT(errors, 0);
}

// The restricted unpickler alone on the real data.pkl, truncated at and corrupted around many positions: only
// dvs::Error may come out (no crash, no other exception, no hang).
TEST(PthVdaFuzz, MutatedStateDictPicklesFailCleanly) {
  const std::string pk = pickle_of(vda_checkpoint_path());
  ASSERT_FALSE(pk.empty());
  auto parse = [&](const std::string& b) { dvs::parse_state_dict_pickle({reinterpret_cast<const uint8_t*>(b.data()), b.size()}, "x.pth"); };
  EXPECT_NO_THROW(parse(pk));
  EXPECT_EQ(dvs::parse_state_dict_pickle({reinterpret_cast<const uint8_t*>(pk.data()), pk.size()}, "x.pth").tensors.size(),
            vda_cases().at("checkpoint").at("n_tensors").get<size_t>());
  std::mt19937 rng(7);
  int errors = 0, parsed = 0;
  auto run = [&](const std::string& b, const std::string& what) {
    try {
      parse(b);
      ++parsed;
    } catch (const dvs::Error& e) {
      ++errors;
      EXPECT_NE(std::string(e.what()).find("x.pth: data.pkl"), std::string::npos) << what << ": " << e.what();
    } catch (const std::exception& e) {
      ADD_FAILURE() << what << ": not a dvs::Error: " << e.what();
    }
  };
  for (size_t c = 0; c < pk.size(); c += 29) run(pk.substr(0, c), "cut at " + std::to_string(c));
  const std::string opcodes = "\x80}()NXKMJ\x8a" "ctQR" "su" "qrhj" "\x85\x86\x87\x88\x89" "b.G\x93";
  for (size_t pos = 0; pos < pk.size(); pos += 17) {
    std::string b = pk;
    if (rng() % 2) b[pos] = char(uint8_t(b[pos]) ^ uint8_t(1u << (rng() % 8)));
    else b[pos] = opcodes[rng() % opcodes.size()];
    run(b, "byte " + std::to_string(pos) + " changed");
  }
  std::cout << "[ fuzz ] mutated pickles: " << errors << " errors, " << parsed << " parsed\n";
  EXPECT_GT(errors, 0);
}
