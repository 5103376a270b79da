// `dvs-weights merge-lora`, run as a user runs it: the transformer loaded from the merged folder must give the
// output of the base model with the same LoRA applied unmerged (set_lora), on a make-tiny model (f32, one file)
// and on the pack's bf16 model (three shards). Tolerances: f32 1e-5 + 1e-4·|ref| (GEMM summation order only);
// bf16 the merged weight is rounded to bf16 once (relative 2^-9), so 2e-3 + 2e-2·|ref|.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <span>

#include "spec/model_folder.hpp"
#include "io/npy.hpp"
#include "io/safetensors_writer.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/cogvideox/lora.hpp"
#include "support/files.hpp"
#include "support/gpu.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

class MergeLora : public test::GpuTest {};

std::vector<float> normals(size_t n, uint32_t seed, double sd) {
  std::mt19937 g(seed);
  std::normal_distribution<double> d(0.0, sd);
  std::vector<float> v(n);
  for (float& x : v) x = float(d(g));
  return v;
}

test::CommandResult weights_tool(const std::string& args) {
  return test::run_command(test::program("dvs-weights") + " " + args);
}

struct LoraModule {
  std::string module;
  double alpha;  // 0: no alpha entry
};

// A rank-4 LoRA on four attention projections (one with alpha), in diffusers' saved layout.
std::map<std::string, std::pair<std::vector<float>, std::vector<float>>> write_lora(const fs::path& file, int64_t D,
                                                                                  const std::vector<LoraModule>& mods) {
  const int64_t r = 4;
  std::vector<std::pair<std::string, HostTensor>> t;
  std::map<std::string, std::pair<std::vector<float>, std::vector<float>>> ab;
  uint32_t seed = 40;
  for (const auto& m : mods) {
    auto a = normals(size_t(r * D), seed++, 1.0 / std::sqrt(double(D)));
    auto b = normals(size_t(D * r), seed++, 0.5);
    t.emplace_back("transformer." + m.module + ".lora_A.weight", HostTensor::from_f32({r, D}, a));
    t.emplace_back("transformer." + m.module + ".lora_B.weight", HostTensor::from_f32({D, r}, b));
    if (m.alpha > 0) t.emplace_back("transformer." + m.module + ".alpha", HostTensor::from_f32({}, std::vector<float>{float(m.alpha)}));
    ab[m.module] = {a, b};
  }
  write_safetensors(file, t);
  return ab;
}

const std::vector<LoraModule> kModules = {{"transformer_blocks.0.attn1.to_q", 0},
                                          {"transformer_blocks.0.attn1.to_v", 0},
                                          {"transformer_blocks.1.attn1.to_k", 0},
                                          {"transformer_blocks.1.attn1.to_out.0", 8}};

std::vector<float> forward(vk::Context& ctx, models::CogVideoXTransformer& tr, uint32_t seed) {
  const auto& c = tr.config();
  const int64_t F = (c.sample_frames - 1) / c.temporal_compression_ratio + 1;
  const Shape lat{1, F, c.in_channels, c.sample_height, c.sample_width}, txt{1, c.max_text_seq_length, c.text_embed_dim};
  const Tensor l = Tensor::upload(ctx, HostTensor::from_f32(lat, normals(size_t(shape_numel(lat)), seed, 1.0)));
  const Tensor x = Tensor::upload(ctx, HostTensor::from_f32(txt, normals(size_t(shape_numel(txt)), seed + 1, 1.0)));
  const float t = 700.0f;
  return tr.forward(l, x, std::span<const float>(&t, 1)).download(ctx).to_f32();
}

bool same_bytes(const fs::path& a, const fs::path& b) {
  std::ifstream fa(a, std::ios::binary), fb(b, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(fa), {}) == std::string(std::istreambuf_iterator<char>(fb), {});
}

// Merges, then compares merged vs unmerged outputs and checks the folder around the transformer.
void check_merge(vk::Context& ctx, const fs::path& model, const test::TempDir& dir, double abs_tol, double rel_tol) {
  const json cfg = read_json_file(model / "transformer" / "config.json");
  const int64_t D = cfg.at("num_attention_heads").get<int64_t>() * cfg.at("attention_head_dim").get<int64_t>();
  const fs::path lora = dir / "lora.safetensors", out = dir / "merged";
  const auto ab = write_lora(lora, D, kModules);
  const float user_scale = 0.7f;
  const auto r = weights_tool("merge-lora --model '" + model.string() + "' --lora '" + lora.string() + ":0.7' --out '" +
                              out.string() + "'");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("merged 4 LoRA module(s)"), std::string::npos) << r.output;

  // Same files as the input, other components byte for byte.
  for (auto it = fs::recursive_directory_iterator(model); it != fs::recursive_directory_iterator(); ++it) {
    if (!it->is_regular_file()) continue;
    const fs::path rel = fs::relative(it->path(), model);
    ASSERT_TRUE(fs::exists(out / rel)) << rel;
    if (rel.begin()->string() != "transformer" || rel.extension() != ".safetensors")
      EXPECT_TRUE(same_bytes(it->path(), out / rel)) << rel;
  }
  for (const auto& e : fs::directory_iterator(dir.path))
    EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << "left behind: " << e.path();

  // One merged weight against W + s·(alpha/r)·B·A computed here in double precision, then stored-dtype rounding.
  const WeightSet in_w = WeightSet::open_dir(model / "transformer"), out_w = WeightSet::open_dir(out / "transformer");
  EXPECT_EQ(in_w.files().size(), out_w.files().size()) << "sharded like the input";
  const std::string probe = "transformer_blocks.1.attn1.to_out.0";
  const HostTensor w0 = in_w.load(probe + ".weight"), w1 = out_w.load(probe + ".weight");
  EXPECT_EQ(w0.dtype, w1.dtype) << "stored dtype kept";
  const auto f0 = w0.to_f32(), f1 = w1.to_f32();
  const auto& [a, b] = ab.at(probe);
  const double s = user_scale * 8.0 / 4.0;
  double max_dev = 0;
  for (int64_t o = 0; o < D; ++o)
    for (int64_t i = 0; i < D; ++i) {
      double d = 0;
      for (int64_t k = 0; k < 4; ++k) d += double(b[size_t(o * 4 + k)]) * double(a[size_t(k * D + i)]);
      const double want = double(f0[size_t(o * D + i)]) + s * d;
      max_dev = std::max(max_dev, std::fabs(double(f1[size_t(o * D + i)]) - want) / std::max(1.0, std::fabs(want)));
    }
  EXPECT_LE(max_dev, w0.dtype == DType::f32 ? 1e-6 : 1.0 / 256.0) << probe;
  // Untouched tensors are bit-identical.
  EXPECT_EQ(in_w.load("transformer_blocks.0.attn1.to_k.weight").data, out_w.load("transformer_blocks.0.attn1.to_k.weight").data);

  // The model's output: merged folder vs base + set_lora.
  models::CogVideoXTransformer base(ctx, model / "transformer");
  const auto plain = forward(ctx, base, 11);
  base.set_lora(models::load_lora(ctx, lora, user_scale));
  const auto unmerged = forward(ctx, base, 11);
  models::CogVideoXTransformer merged(ctx, out / "transformer");
  const auto ours = forward(ctx, merged, 11);
  ASSERT_EQ(ours.size(), unmerged.size());
  double max_err = 0, effect = 0;
  for (size_t i = 0; i < ours.size(); ++i) {
    const double ref = unmerged[i];
    max_err = std::max(max_err, std::fabs(double(ours[i]) - ref));
    effect = std::max(effect, std::fabs(ref - double(plain[i])));
    ASSERT_LE(std::fabs(double(ours[i]) - ref), abs_tol + rel_tol * std::fabs(ref)) << i;
  }
  std::cout << "[merge-lora] " << model.filename().string() << ": merged vs unmerged max |err| " << max_err
            << "; the LoRA moves the output by up to " << effect << "\n";
  EXPECT_GT(effect, 10 * abs_tol) << "the LoRA must change the output more than the tolerance";
}

TEST_F(MergeLora, TinyF32ModelMatchesUnmergedLora) {
  test::TempDir dir;
  const auto made = weights_tool("make-tiny --out '" + (dir / "tiny").string() + "' --seed 5");
  ASSERT_EQ(made.exit_code, 0) << made.output;
  check_merge(ctx(), dir / "tiny", dir, 1e-5, 1e-4);
}

TEST_F(MergeLora, ShardedBf16PackMatchesUnmergedLora) {
  const fs::path model = test::golden_path() / "model_bf16";
  if (!fs::exists(model / "transformer")) GTEST_SKIP() << "no bf16 pack";
  test::TempDir dir;
  check_merge(ctx(), model, dir, 2e-3, 2e-2);
}

TEST(MergeLoraCli, BadInputIsAClearErrorAndLeavesNothing) {
  test::TempDir dir;
  const auto made = weights_tool("make-tiny --out '" + (dir / "tiny").string() + "'");
  ASSERT_EQ(made.exit_code, 0) << made.output;
  const json cfg = read_json_file(dir / "tiny" / "transformer" / "config.json");
  const int64_t D = cfg.at("num_attention_heads").get<int64_t>() * cfg.at("attention_head_dim").get<int64_t>();
  write_lora(dir / "wrong.safetensors", D, {{"transformer_blocks.9.attn1.to_q", 0}});
  write_lora(dir / "good.safetensors", D, {{"transformer_blocks.0.attn1.to_q", 0}});
  const std::string m = " --model '" + (dir / "tiny").string() + "'";
  struct Case {
    std::string args;
    int status;
    std::string expect;
  };
  fs::create_directories(dir / "full");
  test::write_text(dir / "full" / "x.txt", "x");
  const std::vector<Case> cases = {
      {"merge-lora" + m + " --lora '" + (dir / "wrong.safetensors").string() + "' --out '" + (dir / "o1").string() + "'", 1,
       "transformer_blocks.9.attn1.to_q"},
      {"merge-lora" + m + " --lora '" + (dir / "good.safetensors").string() + ":much' --out '" + (dir / "o2").string() + "'",
       1, "scale"},
      {"merge-lora" + m + " --lora '" + (dir / "missing.safetensors").string() + "' --out '" + (dir / "o3").string() + "'",
       1, "no such LoRA file"},
      {"merge-lora" + m + " --lora '" + (dir / "good.safetensors").string() + "' --out '" + (dir / "full").string() + "'", 1,
       "not an empty folder"},
      {"merge-lora --model '" + (dir / "nope").string() + "' --lora '" + (dir / "good.safetensors").string() + "' --out '" +
           (dir / "o4").string() + "'",
       1, "no such model folder"},
      {"merge-lora" + m + " --out '" + (dir / "o5").string() + "'", 2, "--lora"},
      {"merge-lora x y", 2, "unexpected argument"},
  };
  for (const auto& c : cases) {
    const auto r = weights_tool(c.args);
    EXPECT_EQ(r.exit_code, c.status) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.expect), std::string::npos) << c.args << "\n" << r.output;
  }
  for (const char* o : {"o1", "o2", "o3", "o4", "o5"}) EXPECT_FALSE(fs::exists(dir / o)) << o;
  for (const auto& e : fs::directory_iterator(dir.path))
    EXPECT_EQ(e.path().filename().string().find(".partial"), std::string::npos) << "left behind: " << e.path();
}

}  // namespace
}  // namespace dvs
