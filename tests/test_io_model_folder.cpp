// Pipeline folders, sharded weight sets, weight schemas for other sizes, and the dvs-weights program.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "support/expect_error.hpp"
#include "support/files.hpp"
#include "support/process.hpp"
#include "dvs/error.hpp"
#include "spec/model_folder.hpp"
#include "spec/model_schema.hpp"

namespace fs = std::filesystem;
using nlohmann::json;

using dvs::test::golden_path;
using dvs::test::TempDir;
using dvs::test::write_text;

namespace {

json read_json(const fs::path& p) { return json::parse(std::ifstream(p)); }

// A small valid safetensors file holding F32 tensors of the given names (shape [2]).
void put_st(const fs::path& p, const std::vector<std::string>& names) {
  json h = json::object();
  uint64_t off = 0;
  for (const auto& n : names) {
    h[n] = {{"dtype", "F32"}, {"shape", {2}}, {"data_offsets", {off, off + 8}}};
    off += 8;
  }
  const std::string s = h.dump();
  std::string bytes(8, '\0');
  for (int i = 0; i < 8; ++i) bytes[size_t(i)] = char(uint8_t(s.size() >> (8 * i)));
  write_text(p, bytes + s + std::string(size_t(off), '\0'));
}

using dvs::test::expect_error;

const dvs::TensorSpec* spec(const dvs::Schema& s, const std::string& name) {
  for (const auto& t : s.tensors)
    if (t.name == name) return &t;
  return nullptr;
}

struct RunResult {
  int status = -1;
  std::string output;
};

RunResult run(const std::string& args) {
  RunResult r;
  const std::string cmd = dvs::test::program("dvs-weights") + " " + args + " 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  const int st = ::pclose(p);
  r.status = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

}  // namespace

// ---- the pack's folders -------------------------------------------------------------------------------------

TEST(ModelFolder, ListsThePacksComponents) {
  const dvs::ModelFolder m = dvs::ModelFolder::open(golden_path() / "model");
  EXPECT_EQ(m.pipeline_class(), "CogVideoXImageToVideoPipeline");
  std::vector<std::string> names;
  for (const auto& c : m.components()) names.push_back(c.name);
  EXPECT_EQ(names, (std::vector<std::string>{"scheduler", "text_encoder", "tokenizer", "transformer", "vae"}));
  ASSERT_NE(m.find("transformer"), nullptr);
  EXPECT_EQ(m.find("transformer")->library, "diffusers");
  EXPECT_EQ(m.find("text_encoder")->class_name, "T5EncoderModel");
  EXPECT_EQ(m.find("nope"), nullptr);
  EXPECT_EQ(m.config_path("scheduler").filename(), "scheduler_config.json");
  EXPECT_EQ(m.config("transformer")["num_layers"], 2);
  EXPECT_EQ(dvs::config_class_name(m.config("transformer")), "CogVideoXTransformer3DModel");
  EXPECT_EQ(dvs::config_class_name(m.config("text_encoder")), "T5EncoderModel");
  const dvs::Component tok = m.load("tokenizer");
  EXPECT_FALSE(tok.weights.has_value());
  expect_error([&] { m.weights("scheduler"); }, "scheduler", "no weights");
  expect_error([&] { m.load("unet"); }, "model_index.json", "no component 'unet'");
}

TEST(ModelFolder, SingleFileAndShardedWeightSets) {
  const auto single = dvs::ModelFolder::open(golden_path() / "model").weights("text_encoder");
  const auto sharded = dvs::ModelFolder::open(golden_path() / "model_bf16").weights("text_encoder");
  EXPECT_FALSE(single.sharded());
  EXPECT_TRUE(sharded.sharded());
  EXPECT_EQ(sharded.files().size(), 2u);
  EXPECT_EQ(sharded.source().filename(), "model.safetensors.index.json");
  EXPECT_EQ(single.size(), 21u);
  EXPECT_EQ(sharded.size(), 21u);
  EXPECT_EQ(single.find("encoder.embed_tokens.weight"), nullptr);  // tied to shared.weight, not stored
  const auto a = single.load("shared.weight"), b = sharded.load("shared.weight");
  EXPECT_EQ(a.shape, b.shape);
  EXPECT_EQ(b.dtype, dvs::DType::bf16);
  EXPECT_EQ(sharded.bytes("shared.weight").size(), 128u * 32u * 2u);
  expect_error([&] { sharded.load("missing.weight"); }, "model.safetensors.index.json", "missing.weight");
  // Opening the index file directly gives the same set.
  const auto direct = dvs::WeightSet::open_file(golden_path() / "model_bf16/text_encoder/model.safetensors.index.json");
  EXPECT_EQ(direct.size(), 21u);
}

// ---- broken folders and shard sets ----------------------------------------------------------------------------

TEST(ModelFolderErrors, MissingOrBadModelIndex) {
  TempDir dir;
  expect_error([&] { dvs::ModelFolder::open(dir.path); }, "model_index.json", "not found");
  write_text(dir / "model_index.json", "{\"vae\": [\"diffusers\", ");
  expect_error([&] { dvs::ModelFolder::open(dir.path); }, "model_index.json", "not valid JSON");
  write_text(dir / "model_index.json", "{\"vae\": [\"diffusers\"]}");
  expect_error([&] { dvs::ModelFolder::open(dir.path); }, "model_index.json", "[library, class]");
  write_text(dir / "model_index.json", std::string(200, '[') + std::string(200, ']'));
  expect_error([&] { dvs::ModelFolder::open(dir.path); }, "model_index.json", "nests deeper");
  write_text(dir / "model_index.json", R"({"_class_name": "P", "vae": ["diffusers", "AutoencoderKLCogVideoX"],
                                         "safety_checker": [null, null], "requires_safety_checker": false})");
  const auto m = dvs::ModelFolder::open(dir.path);
  ASSERT_EQ(m.components().size(), 1u);
  expect_error([&] { m.load("vae"); }, "vae", "component folder listed in model_index.json is missing");
  fs::create_directories(dir / "vae");
  expect_error([&] { m.load("vae"); }, "config.json", "not found");
  write_text(dir / "vae/config.json", "{}");
  expect_error([&] { m.weights("vae"); }, "vae", "no weights");
  write_text(dir / "vae/diffusion_pytorch_model.bin", "x");
  expect_error([&] { m.weights("vae"); }, "vae", ".bin");
  expect_error([&] { dvs::ModelFolder::open(dir / "nowhere"); }, "nowhere", "not a folder");
}

TEST(ModelFolderErrors, ShardIndexProblems) {
  TempDir dir;
  const fs::path idx = dir / "model.safetensors.index.json";
  put_st(dir / "s1.safetensors", {"a", "b"});
  put_st(dir / "s2.safetensors", {"c"});

  write_text(idx, R"({"weight_map": {"a": "s1.safetensors", "c": "s2.safetensors", "d": "s3.safetensors"}})");
  expect_error([&] { dvs::WeightSet::open_dir(dir.path); }, "model.safetensors.index.json", "shard 's3.safetensors'");
  expect_error([&] { dvs::WeightSet::open_dir(dir.path); }, "model.safetensors.index.json", "missing");

  write_text(idx, R"({"weight_map": {"a": "s1.safetensors", "z": "s2.safetensors"}})");
  expect_error([&] { dvs::WeightSet::open_dir(dir.path); }, "model.safetensors.index.json", "'z'");
  expect_error([&] { dvs::WeightSet::open_dir(dir.path); }, "s2.safetensors", "does not contain it");

  put_st(dir / "s3.safetensors", {"b"});
  write_text(idx, R"({"weight_map": {"a": "s1.safetensors", "b": "s3.safetensors"}})");
  expect_error([&] { dvs::WeightSet::open_dir(dir.path); }, "s1.safetensors", "present in two shards");

  write_text(idx, R"({"weight_map": {"a": "../s1.safetensors"}})");
  expect_error([&] { dvs::WeightSet::open_dir(dir.path); }, "model.safetensors.index.json", "plain file name");
  write_text(idx, R"({"metadata": {}})");
  expect_error([&] { dvs::WeightSet::open_dir(dir.path); }, "model.safetensors.index.json", "weight_map");
  write_text(idx, R"({"weight_map": {"a": 3}})");
  expect_error([&] { dvs::WeightSet::open_dir(dir.path); }, "model.safetensors.index.json", "'a'");

  // A corrupt shard is reported by its own name.
  write_text(dir / "s2.safetensors", "garbage!");
  write_text(idx, R"({"weight_map": {"a": "s1.safetensors", "c": "s2.safetensors"}})");
  expect_error([&] { dvs::WeightSet::open_dir(dir.path); }, "s2.safetensors", "header");

  // Valid, with an unlisted tensor and a wrong total_size: loads, with warnings.
  put_st(dir / "s2.safetensors", {"c"});
  write_text(idx, R"({"metadata": {"total_size": 99}, "weight_map": {"a": "s1.safetensors", "c": "s2.safetensors"}})");
  const auto w = dvs::WeightSet::open_dir(dir.path);
  EXPECT_EQ(w.size(), 2u);
  EXPECT_EQ(w.warnings().size(), 2u);  // 'b' unlisted; total_size 99 != 16
}

TEST(ModelFolderErrors, AmbiguousWeightFiles) {
  TempDir dir;
  put_st(dir / "a.safetensors", {"x"});
  put_st(dir / "b.safetensors", {"y"});
  expect_error([&] { dvs::WeightSet::open_dir(dir.path); }, "a.safetensors", "several .safetensors");
  // The library's standard name wins over variants.
  put_st(dir / "diffusion_pytorch_model.safetensors", {"z"});
  EXPECT_EQ(dvs::WeightSet::open_dir(dir.path).entries().begin()->first, "z");
}

// ---- schemas for other sizes ------------------------------------------------------------------------------------

TEST(ModelFolderSchema, T5FollowsItsConfig) {
  json c = read_json(golden_path() / "model/text_encoder/config.json");
  c["num_layers"] = 3;
  c["num_heads"] = 6;
  c["d_kv"] = 5;
  c["feed_forward_proj"] = "relu";
  const auto s = dvs::t5_encoder_schema(c);
  EXPECT_EQ(s.tensors.size(), 2u + 3u * 8u + 1u + 1u);  // shared, embed_tokens, 3 x (q k v o ln wi wo ln), bias, final
  EXPECT_EQ(spec(s, "encoder.block.2.layer.0.SelfAttention.q.weight")->shape, (dvs::Shape{30, 32}));
  EXPECT_EQ(spec(s, "encoder.block.1.layer.0.SelfAttention.o.weight")->shape, (dvs::Shape{32, 30}));
  EXPECT_EQ(spec(s, "encoder.block.0.layer.0.SelfAttention.relative_attention_bias.weight")->shape, (dvs::Shape{32, 6}));
  EXPECT_EQ(spec(s, "encoder.block.1.layer.0.SelfAttention.relative_attention_bias.weight"), nullptr);
  EXPECT_NE(spec(s, "encoder.block.2.layer.1.DenseReluDense.wi.weight"), nullptr);
  EXPECT_EQ(spec(s, "encoder.block.2.layer.1.DenseReluDense.wi_0.weight"), nullptr);
  EXPECT_TRUE(spec(s, "encoder.embed_tokens.weight")->optional);
  c["feed_forward_proj"] = "gated-silu-x";
  expect_error([&] { dvs::t5_encoder_schema(c, "te/config.json"); }, "te/config.json", "feed_forward_proj");
  c["feed_forward_proj"] = "gated-gelu";
  c["d_model"] = "big";
  expect_error([&] { dvs::t5_encoder_schema(c, "te/config.json"); }, "te/config.json", "'d_model'");
  c["d_model"] = -4;
  expect_error([&] { dvs::t5_encoder_schema(c, "te/config.json"); }, "te/config.json", "out of range");
}

TEST(ModelFolderSchema, TransformerFollowsItsConfig) {
  json c = read_json(golden_path() / "model/transformer/config.json");
  c["num_attention_heads"] = 3;
  c["attention_head_dim"] = 8;
  c["num_layers"] = 4;
  c["attention_bias"] = false;
  const auto s = dvs::cogvideox_transformer_schema(c);
  EXPECT_EQ(spec(s, "transformer_blocks.3.attn1.to_q.weight")->shape, (dvs::Shape{24, 24}));
  EXPECT_EQ(spec(s, "transformer_blocks.3.attn1.to_q.bias"), nullptr);
  EXPECT_NE(spec(s, "transformer_blocks.3.attn1.to_out.0.bias"), nullptr);
  EXPECT_EQ(spec(s, "transformer_blocks.0.attn1.norm_k.weight")->shape, (dvs::Shape{8}));
  EXPECT_EQ(spec(s, "transformer_blocks.2.norm1.linear.weight")->shape, (dvs::Shape{144, 32}));
  EXPECT_EQ(spec(s, "transformer_blocks.1.ff.net.0.proj.weight")->shape, (dvs::Shape{96, 24}));
  EXPECT_EQ(spec(s, "patch_embed.pos_embedding")->shape, (dvs::Shape{1, 8 + 3 * 4 * 4, 24}));
  EXPECT_EQ(spec(s, "proj_out.weight")->shape, (dvs::Shape{16, 24}));
  EXPECT_EQ(spec(s, "transformer_blocks.4.norm1.linear.weight"), nullptr);

  // CogVideoX 1.5 style: temporal patches, ofs embedding, no learned positions.
  c["patch_size_t"] = 2;
  c["ofs_embed_dim"] = 16;
  c["use_learned_positional_embeddings"] = false;
  c["activation_fn"] = "geglu";
  const auto s15 = dvs::cogvideox_transformer_schema(c);
  EXPECT_EQ(spec(s15, "patch_embed.proj.weight")->shape, (dvs::Shape{24, 8 * 2 * 2 * 2}));
  EXPECT_EQ(spec(s15, "patch_embed.pos_embedding"), nullptr);
  EXPECT_EQ(spec(s15, "ofs_embedding.linear_2.weight")->shape, (dvs::Shape{16, 16}));
  EXPECT_EQ(spec(s15, "proj_out.weight")->shape, (dvs::Shape{2 * 2 * 2 * 4, 24}));
  EXPECT_EQ(spec(s15, "transformer_blocks.0.ff.net.0.proj.weight")->shape, (dvs::Shape{192, 24}));
  c["activation_fn"] = "mish";
  expect_error([&] { dvs::cogvideox_transformer_schema(c, "tr/config.json"); }, "tr/config.json", "activation_fn");

  // The real CogVideoX-5B-I2V sizes.
  json real = read_json(golden_path() / "model/transformer/config.json");
  real["num_attention_heads"] = 48;
  real["attention_head_dim"] = 64;
  real["num_layers"] = 42;
  real["time_embed_dim"] = 512;
  real["text_embed_dim"] = 4096;
  real["max_text_seq_length"] = 226;
  real["in_channels"] = 32;
  real["out_channels"] = 16;
  real["sample_frames"] = 49;
  real["sample_height"] = 60;
  real["sample_width"] = 90;
  const auto r = dvs::cogvideox_transformer_schema(real);
  EXPECT_EQ(spec(r, "patch_embed.pos_embedding")->shape, (dvs::Shape{1, 17776, 3072}));
  EXPECT_EQ(spec(r, "patch_embed.proj.weight")->shape, (dvs::Shape{3072, 32, 2, 2}));
  EXPECT_EQ(spec(r, "transformer_blocks.41.ff.net.0.proj.weight")->shape, (dvs::Shape{12288, 3072}));
  EXPECT_EQ(r.tensors.size(), 17u + 42u * 24u);
}

TEST(ModelFolderSchema, VaeFollowsItsConfig) {
  json c = read_json(golden_path() / "model/vae/config.json");
  c["block_out_channels"] = {4, 8, 12};
  c["down_block_types"] = json::array({"CogVideoXDownBlock3D", "CogVideoXDownBlock3D", "CogVideoXDownBlock3D"});
  c["up_block_types"] = json::array({"CogVideoXUpBlock3D", "CogVideoXUpBlock3D", "CogVideoXUpBlock3D"});
  c["layers_per_block"] = 2;
  c["latent_channels"] = 6;
  c["use_quant_conv"] = true;
  const auto s = dvs::cogvideox_vae_schema(c);
  EXPECT_EQ(spec(s, "encoder.conv_out.conv.weight")->shape, (dvs::Shape{12, 12, 3, 3, 3}));
  EXPECT_EQ(spec(s, "encoder.down_blocks.2.resnets.0.conv_shortcut.weight")->shape, (dvs::Shape{12, 8, 1, 1, 1}));
  EXPECT_EQ(spec(s, "encoder.down_blocks.2.resnets.1.conv_shortcut.weight"), nullptr);
  EXPECT_EQ(spec(s, "encoder.down_blocks.2.downsamplers.0.conv.weight"), nullptr);  // last block: none
  EXPECT_EQ(spec(s, "encoder.down_blocks.1.downsamplers.0.conv.weight")->shape, (dvs::Shape{8, 8, 3, 3}));
  EXPECT_EQ(spec(s, "decoder.up_blocks.0.resnets.2.norm2.conv_y.conv.weight")->shape, (dvs::Shape{12, 6, 1, 1, 1}));
  EXPECT_EQ(spec(s, "decoder.up_blocks.0.resnets.3.conv1.conv.weight"), nullptr);  // layers_per_block + 1
  EXPECT_EQ(spec(s, "decoder.up_blocks.2.resnets.0.conv_shortcut.weight")->shape, (dvs::Shape{4, 8, 1, 1, 1}));
  EXPECT_EQ(spec(s, "decoder.norm_out.norm_layer.weight")->shape, (dvs::Shape{4}));
  EXPECT_EQ(spec(s, "decoder.conv_in.conv.weight")->shape, (dvs::Shape{12, 6, 3, 3, 3}));
  EXPECT_EQ(spec(s, "quant_conv.weight")->shape, (dvs::Shape{6, 6, 1, 1, 1}));
  EXPECT_EQ(spec(s, "post_quant_conv.weight"), nullptr);
  c["up_block_types"] = json::array({"CogVideoXUpBlock3D"});
  expect_error([&] { dvs::cogvideox_vae_schema(c, "vae/config.json"); }, "vae/config.json", "up_block_types");
  c["up_block_types"] = json::array({"UpBlock2D", "CogVideoXUpBlock3D", "CogVideoXUpBlock3D"});
  expect_error([&] { dvs::cogvideox_vae_schema(c, "vae/config.json"); }, "vae/config.json", "UpBlock2D");
  expect_error([&] { dvs::schema_for("UNet2DConditionModel", c, "unet/config.json"); }, "unet/config.json", "no weight schema");
}

TEST(ModelFolderSchema, ReportsEveryMismatch) {
  const dvs::ModelFolder m = dvs::ModelFolder::open(golden_path() / "model");
  const auto cfg = m.config("transformer");
  const auto s = dvs::schema_for("CogVideoXTransformer3DModel", cfg);
  std::vector<std::pair<std::string, dvs::Shape>> found;
  for (const auto& t : s.tensors) found.emplace_back(t.name, t.shape);
  EXPECT_TRUE(dvs::check_schema(s, found).empty());
  found.erase(found.begin());                                       // patch_embed.proj.weight missing
  for (auto& [n, sh] : found)
    if (n == "proj_out.weight") sh = {17, 32};                      // wrong shape
  found.emplace_back("transformer_blocks.2.attn1.to_q.weight", dvs::Shape{32, 32});  // unexpected
  const auto issues = dvs::check_schema(s, found);
  ASSERT_EQ(issues.size(), 3u);
  std::string all;
  for (const auto& i : issues) all += i.message() + "\n";
  EXPECT_NE(all.find("'patch_embed.proj.weight' is missing (expected shape [32,8,2,2])"), std::string::npos) << all;
  EXPECT_NE(all.find("'proj_out.weight': expected shape [16,32], found [17,32]"), std::string::npos) << all;
  EXPECT_NE(all.find("'transformer_blocks.2.attn1.to_q.weight' is unexpected"), std::string::npos) << all;
  // The real files pass require_schema; a mismatching schema throws naming the source.
  const auto w = m.weights("transformer");
  EXPECT_NO_THROW(dvs::require_schema(s, w, "transformer"));
  auto cfg3 = cfg;
  cfg3["num_layers"] = 3;
  expect_error([&] { dvs::require_schema(dvs::cogvideox_transformer_schema(cfg3), w, "my/transformer"); }, "my/transformer",
               "transformer_blocks.2.attn1.to_q.weight' is missing");
}

// ---- the dvs-weights program ---------------------------------------------------------------------------------

TEST(IoWeightsTool, InspectsThePackAndRejectsACorruptFile) {
  ASSERT_TRUE(fs::exists(dvs::test::program("dvs-weights"))) << "build the dvs-weights target first";
  for (const char* folder : {"model", "model_bf16"}) {
    const auto r = run("inspect '" + (golden_path() / folder).string() + "'");
    EXPECT_EQ(r.status, 0) << r.output;
    EXPECT_NE(r.output.find("patch_embed.pos_embedding"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("encoder.block.0.layer.0.SelfAttention.relative_attention_bias.weight"), std::string::npos);
    EXPECT_NE(r.output.find("schema: OK, matches AutoencoderKLCogVideoX"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("mismatch"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("overall: 3 component(s) with weights, 326 tensors"), std::string::npos) << r.output;
  }
  const auto one = run("inspect --summary '" + (golden_path() / "model/vae/diffusion_pytorch_model.safetensors").string() + "'");
  EXPECT_EQ(one.status, 0) << one.output;
  EXPECT_NE(one.output.find("240 tensors"), std::string::npos) << one.output;

  TempDir dir;
  write_text(dir / "broken.safetensors", std::string("\x10\0\0\0\0\0\0\0{\"a\":", 13));
  const auto bad = run("inspect '" + (dir / "broken.safetensors").string() + "'");
  EXPECT_NE(bad.status, 0);
  EXPECT_NE(bad.output.find("broken.safetensors"), std::string::npos) << bad.output;

  // A component whose weights do not fit its config: non-zero, and the mismatch is printed.
  fs::create_directories(dir / "tr");
  fs::copy_file(golden_path() / "model/transformer/diffusion_pytorch_model.safetensors",
                dir / "tr/diffusion_pytorch_model.safetensors");
  json cfg = read_json(golden_path() / "model/transformer/config.json");
  cfg["num_layers"] = 3;
  write_text(dir / "tr/config.json", cfg.dump());
  const auto mis = run("inspect '" + (dir / "tr").string() + "'");
  EXPECT_EQ(mis.status, 1) << mis.output;
  EXPECT_NE(mis.output.find("transformer_blocks.2.attn1.to_q.weight' is missing"), std::string::npos) << mis.output;

  EXPECT_EQ(run("--help").status, 0);
  EXPECT_NE(run("--help").output.find("inspect PATH"), std::string::npos);
  const auto tiny = run("make-tiny");
  EXPECT_NE(tiny.status, 0);
  EXPECT_NE(tiny.output.find("--out"), std::string::npos) << tiny.output;
  EXPECT_EQ(run("merge-lora x y").status, 2);
  EXPECT_EQ(run("frobnicate").status, 2);
  EXPECT_EQ(run("inspect").status, 2);
}
