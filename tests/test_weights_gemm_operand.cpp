// GEMM operands kept in the tensor cores' operand type. Weights (ComponentWeights::store_as, DeviceTuning::linear_weights_fp16):
// a bf16 weight asked for as f16 reaches the device as fp16, each value the bf16 one rounded to nearest even (checked
// against the file's own bytes converted here), from files (resident and through the streaming host copy) and from
// tensors already on the device; other tensors keep their dtype; a weight with a finite value past fp16's range
// stays bf16. On a device whose linear family is coopmat (the tensor-core pass), the transformer keeps its Linear
// weights fp16 and writes its LayerNorm and GELU outputs fp16 (DeviceTuning::linear_activations_fp16), and computes the same
// bytes as with the per-element conversions in the GEMM's loads.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <unistd.h>

#include "io/safetensors_writer.hpp"
#include "io/weight_set.hpp"
#include "models/cogvideox/cogvideox_transformer.hpp"
#include "models/random/tiny_model.hpp"
#include "models/weights.hpp"
#include "support/gpu.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_linear.hpp"
#include "vk/pipeline.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;

// The bf16 words of `n` normal values (std `scale`), a few tiny ones among them (fp16 subnormals, where rounding
// matters most) and ±0.
HostTensor bf16_values(const Shape& shape, float scale, uint32_t seed) {
  HostTensor h(shape, DType::bf16);
  std::mt19937 rng(seed);
  std::normal_distribution<float> n(0.0f, scale);
  for (int64_t i = 0; i < h.numel(); ++i) {
    float v = n(rng);
    if (i % 7 == 3) v *= 1e-4f;  // 1e-5..1e-4 x scale: fp16 subnormals
    if (i == 5) v = -0.0f;
    h.as<uint16_t>()[i] = f32_to_bf16(v);
  }
  return h;
}

// What the device must hold for `stored` (bf16 words): each value rounded to fp16 by the host's reference conversion.
std::vector<uint16_t> expected_f16(const uint16_t* stored, size_t n) {
  std::vector<uint16_t> out(n);
  for (size_t i = 0; i < n; ++i) out[i] = f32_to_f16(bf16_to_f32(stored[i]));
  return out;
}

std::vector<uint16_t> words(const HostTensor& h) { return {h.as<uint16_t>(), h.as<uint16_t>() + h.numel()}; }

class GemmWeights : public test::GpuTest {
 protected:
  void TearDown() override {
    for (const auto& d : dirs_) fs::remove_all(d);
    test::GpuTest::TearDown();
  }
  fs::path folder(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() / ("dvs_gemm_weights_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    dirs_.push_back(dir);
    return dir;
  }
  std::vector<fs::path> dirs_;
};

TEST_F(GemmWeights, FileTensorsAreConvertedOnceAsTheyAreRead) {
  const fs::path dir = folder("file");
  const HostTensor w = bf16_values({37, 29}, 0.05f, 1), norm = bf16_values({29}, 1.0f, 2);
  HostTensor big = bf16_values({3, 5}, 0.05f, 3);
  big.as<uint16_t>()[7] = f32_to_bf16(70000.0f);  // past fp16's largest finite value, 65504
  write_safetensors(dir / "model.safetensors", {{"lin.weight", w}, {"norm.weight", norm}, {"big.weight", big}});
  std::ofstream(dir / "config.json") << R"({"_class_name": "NoSchema"})";

  models::ComponentWeights cw(ctx(), dir);
  EXPECT_TRUE(cw.store_as("lin.weight", DType::f16));
  EXPECT_TRUE(cw.store_as("lin.weight", DType::f16));  // asking twice changes nothing
  EXPECT_FALSE(cw.store_as("big.weight", DType::f16));
  EXPECT_EQ(cw.info("lin.weight").dtype, DType::f16);
  EXPECT_EQ(cw.info("lin.weight").bytes, w.bytes());
  EXPECT_EQ(cw.info("norm.weight").dtype, DType::bf16);
  EXPECT_EQ(cw.info("big.weight").dtype, DType::bf16);

  const std::vector<uint16_t> want = expected_f16(w.as<uint16_t>(), size_t(w.numel()));
  // The streaming path's host copy.
  std::vector<uint16_t> host(size_t(w.numel()));
  cw.copy_to_host("lin.weight", host.data());
  EXPECT_EQ(host, want);
  // The resident upload.
  const Tensor& t = cw.get("lin.weight");
  EXPECT_EQ(t.dtype(), DType::f16);
  EXPECT_EQ(t.shape(), w.shape);
  EXPECT_EQ(words(t.download(ctx())), want);
  // Untouched tensors: their stored words.
  EXPECT_EQ(words(cw.get("norm.weight").download(ctx())), words(norm));
  EXPECT_EQ(words(cw.get("big.weight").download(ctx())), words(big));
}

TEST_F(GemmWeights, TensorsAlreadyOnTheDeviceAreConvertedThere) {
  const HostTensor w = bf16_values({53, 19}, 0.05f, 4);  // an odd element count: the cast's tail
  std::map<std::string, Tensor> tensors;
  tensors.emplace("lin.weight", Tensor::upload(ctx(), w, "lin"));
  tensors.emplace("f32.weight", Tensor::upload(ctx(), HostTensor::from_f32({3}, std::vector<float>{1, 2, 3}), "f32"));
  models::ComponentWeights cw(ctx(), nlohmann::json{{"_class_name", "NoSchema"}}, std::move(tensors), "in memory");
  EXPECT_TRUE(cw.store_as("lin.weight", DType::f16));
  EXPECT_FALSE(cw.store_as("f32.weight", DType::f16));
  const Tensor& t = cw.get("lin.weight");
  EXPECT_EQ(t.dtype(), DType::f16);
  EXPECT_EQ(words(t.download(ctx())), expected_f16(w.as<uint16_t>(), size_t(w.numel())));
  EXPECT_EQ(cw.get("f32.weight").dtype(), DType::f32);
}

// The tensor-core pass (DVS_TUNING=gpu-coopmat on Mesa 26.1): a bf16 transformer keeps every Linear weight fp16 (and
// nothing else), resident or streamed, its LayerNorms, its attention and its FFN's first GEMM write the next GEMMs'
// input in fp16, its attention reads Q, K and V in fp16 (head-major, from ops::attention_heads: the f16-X and f16-Y
// GEMM pipelines and an attention pipeline with f16 Q, K, V and out run), and its output is the
// same bytes with either switch off (linear_weights_fp16, linear_activations_fp16). Bands of 5 tile rows and 16-key
// attention tiles throughout (the same in every run) make the pipelines this test creates its own.
TEST_F(GemmWeights, TransformerKeepsGemmOperandsFp16WithTheSameResult) {
  if (ops::gemm_weight_dtype(ctx().caps()) != DType::f16)
    GTEST_SKIP() << "the linear family is not coopmat on this device (the tensor-core pass runs this)";
  // (An override replaces the one in force: the runs below name these too.)
  const std::string mine = "linear_coopmat_group_m=5,attention_block_k=16";
  ops::ScopedTuningOverride bands(mine);
  const fs::path dir = folder("transformer");
  models::TinyModelSpec spec;
  spec.dtype = DType::bf16;
  models::write_tiny_model(dir, spec);
  auto run = [&](models::WeightResidency residency, DType want_linear) {
    models::CogVideoXTransformer tr(ctx(), dir / "transformer", residency);
    EXPECT_EQ(tr.block_weight(0, "attn1.to_q.weight").dtype(), want_linear);
    EXPECT_EQ(tr.block_weight(1, "ff.net.2.weight").dtype(), want_linear);
    EXPECT_EQ(tr.block_weight(0, "attn1.norm_q.weight").dtype(), DType::bf16);
    EXPECT_EQ(tr.weights().get("proj_out.weight").dtype(), want_linear);
    EXPECT_EQ(tr.weights().get("patch_embed.proj.weight").dtype(), DType::bf16);  // a convolution's, not a Linear's
    const auto& c = tr.config();
    HostTensor lat({1, 2, c.in_channels, c.sample_height, c.sample_width}, DType::f32);
    HostTensor txt({1, c.max_text_seq_length, c.text_embed_dim}, DType::f32);
    std::mt19937 rng(9);
    std::normal_distribution<float> n;
    for (int64_t i = 0; i < lat.numel(); ++i) lat.as<float>()[i] = n(rng);
    for (int64_t i = 0; i < txt.numel(); ++i) txt.as<float>()[i] = n(rng);
    const float t = 500.0f;
    return words(tr.forward(Tensor::upload(ctx(), lat), Tensor::upload(ctx(), txt), std::span<const float>(&t, 1))
                     .download(ctx()));
  };
  // Whether a tensor-core GEMM pipeline of this test (bands of 5) read an f16 X / wrote an f16 Y.
  auto ran = [&](size_t spec_index) {
    bool found = false;
    ctx().pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name == "linalg/linear_coopmat" && pl.spec.size() == 15 && pl.spec[11] == 5 && pl.spec[spec_index] == 1)
        found = true;
    });
    return found;
  };
  // Whether a tensor-core attention pipeline of this test (head_dim 16, 16-key tiles) read f16 Q, K and V and wrote
  // an f16 out.
  auto attention_f16 = [&] {
    bool found = false;
    ctx().pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name.starts_with("nn/attention_flash_coopmat") && pl.spec.size() == 11 && pl.spec[0] == 16 &&
          pl.spec[1] == 16 && pl.spec[8] == 1 && pl.spec[9] == 1 && pl.spec[10] == 1)
        found = true;
    });
    return found;
  };
  const size_t f16_x = 13, f16_y = 14;
  ASSERT_FALSE(ran(f16_x) || ran(f16_y) || attention_f16());
  const std::vector<uint16_t> both = run(models::WeightResidency::resident, DType::f16);
  EXPECT_TRUE(ran(f16_x)) << "no GEMM read an f16 X";
  EXPECT_TRUE(ran(f16_y)) << "no GEMM wrote an f16 Y (the FFN's GELU output)";
  EXPECT_TRUE(attention_f16()) << "the attention did not read Q, K, V and write to_out's X in f16";
  EXPECT_EQ(run(models::WeightResidency::stream, DType::f16), both);
  {
    ops::ScopedTuningOverride off(mine + ",linear_weights_fp16=off");
    EXPECT_EQ(run(models::WeightResidency::resident, DType::bf16), both) << "weights converted in the loads";
  }
  {
    ops::ScopedTuningOverride off(mine + ",linear_activations_fp16=off");
    EXPECT_EQ(run(models::WeightResidency::resident, DType::f16), both) << "X f32, converted in the loads";
  }
  ops::ScopedTuningOverride off(mine + ",linear_weights_fp16=off,linear_activations_fp16=off");
  EXPECT_EQ(run(models::WeightResidency::resident, DType::bf16), both) << "both converted in the loads";
}

}  // namespace
}  // namespace dvs
