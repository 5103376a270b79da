// Tiny random-weight model folders: loadable by every dvs reader, schema-clean, deterministic per seed.
#include <gtest/gtest.h>

#include <fstream>

#include "dvs/error.hpp"
#include "spec/model_folder.hpp"
#include "spec/model_schema.hpp"
#include "models/cogvideox/cogvideox_vae.hpp"
#include "models/random/tiny_model.hpp"
#include "models/cogvideox/tokenizer.hpp"
#include "support/files.hpp"
#include "support/gpu.hpp"
#include "support/process.hpp"

namespace dvs::models {
namespace {

std::string file_bytes(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), {}};
}

using test::GpuTest;

TEST_F(GpuTest, TinyModelLoadsEverywhere) {
  test::TempDir d;
  TinyModelSpec spec;
  spec.seed = 5;
  spec.dtype = DType::bf16;
  spec.layers = 1;
  write_tiny_model(d.path, spec);
  ModelFolder m = ModelFolder::open(d.path);
  for (const char* c : {"text_encoder", "transformer", "vae"}) {
    Component comp = m.load(c);
    ASSERT_TRUE(comp.weights.has_value()) << c;
    EXPECT_TRUE(check_schema(schema_for(comp.entry.class_name, comp.config), *comp.weights).empty()) << c;
  }
  T5Tokenizer tok = T5Tokenizer::load(d.path);
  auto ids = tok.encode_padded("a red fox walks along the beach", spec.text_len);
  EXPECT_EQ(int(ids.size()), spec.text_len);
  // The VAE runs on it: 5 frames of 16x16 → 2 latent frames of 2x2.
  CogVideoXVae vae(ctx(), d.path / "vae");
  HostTensor video({1, 3, 5, 16, 16}, DType::f32);
  for (int64_t i = 0; i < video.numel(); ++i) video.as<float>()[i] = float(i % 17) / 17.0f - 0.5f;
  VaePosterior post = vae.encode(Tensor::upload(ctx(), video));
  EXPECT_EQ(post.mean.shape(), (Shape{1, spec.latent_channels, 2, 2, 2}));
}

TEST(TinyModel, SameSeedSameBytesOtherSeedDiffers) {
  test::TempDir a, b, c;
  TinyModelSpec spec;
  spec.seed = 1;
  write_tiny_model(a.path, spec);
  write_tiny_model(b.path, spec);
  spec.seed = 2;
  write_tiny_model(c.path, spec);
  const char* w = "transformer/diffusion_pytorch_model.safetensors";
  EXPECT_TRUE(file_bytes(a / w) == file_bytes(b / w));
  EXPECT_TRUE(file_bytes(a / w) != file_bytes(c / w));
  // The vocabulary is the same too (the model file itself records its training paths).
  const char* text = "a small boat sleeps under the snowy forest";
  EXPECT_EQ(T5Tokenizer::load(a.path).encode(text), T5Tokenizer::load(b.path).encode(text));
}

TEST(TinyModel, InvalidSizesAreRefusedAndCliWorks) {
  test::TempDir d;
  TinyModelSpec spec;
  spec.head_dim = 24;
  EXPECT_THROW(write_tiny_model(d.path, spec), Error);
  auto r = test::run_command(test::program("dvs-weights") + " make-tiny --out " + (d / "m").string() + " --layers 1 --seed 7");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  auto ins = test::run_command(test::program("dvs-weights") + " inspect --summary " + (d / "m").string());
  EXPECT_EQ(ins.exit_code, 0) << ins.output;
  auto bad = test::run_command(test::program("dvs-weights") + " make-tiny --out " + (d / "x").string() + " --heads zero");
  EXPECT_NE(bad.exit_code, 0);
  EXPECT_NE(bad.output.find("--heads"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace dvs::models
