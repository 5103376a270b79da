// Golden checks of the T5 v1.1 encoder against the pack's cases t5_masked, t5_nomask, t5_masked_layers,
// t5_text_to_embeddings, t5_e2e_prompts and bf16_sharded (T5 half). Tolerances are read from cases.json
// (|ours - golden| <= atol + rtol·|golden|, 1e-5 + 1e-4 for pack A); each check prints its max error.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "io/npy.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/cogvideox/tokenizer.hpp"
#include "support/golden_compare.hpp"
#include "support/pack.hpp"
#include "support/precision_rule.hpp"
#include "support/gpu.hpp"

namespace fs = std::filesystem;
using dvs::HostTensor;

namespace {

fs::path pack() { return dvs::test::golden_path(); }
using Tol = dvs::test::PackTolerance;
using dvs::test::pack_npy;
using dvs::test::pack_tolerance;

std::vector<std::vector<int32_t>> id_rows(const HostTensor& t) {
  const auto v = t.to_f32();
  const int64_t L = t.shape.back(), B = t.numel() / L;
  std::vector<std::vector<int32_t>> rows;
  rows.resize(size_t(B));
  for (int64_t b = 0; b < B; ++b)
    for (int64_t l = 0; l < L; ++l) rows[size_t(b)].push_back(int32_t(v[size_t(b * L + l)]));
  return rows;
}

// Compares `ours` (or its row `row` of the outermost dimension) with the pack file `rel`, shapes included, by the
// precision rule for T5's ops (support/precision_rule.hpp: the case's tolerance, or 2x PyTorch's bf16 run under
// 16-bit-operand kernels).
void expect_close(const std::string& what, const HostTensor& ours, const std::string& rel, Tol tol, int64_t row = -1) {
  if (row < 0) {
    dvs::test::expect_golden(what, ours, rel, tol.atol, tol.rtol, dvs::test::kTextOps);
    return;
  }
  HostTensor part(dvs::Shape(ours.shape.begin() + 1, ours.shape.end()), ours.dtype);
  std::copy_n(ours.data.begin() + long(size_t(row) * part.bytes()), part.bytes(), part.data.begin());
  dvs::test::expect_golden(what, part, rel, tol.atol, tol.rtol, dvs::test::kTextOps);
}


}  // namespace

class GoldenT5 : public dvs::test::GpuTest {};

TEST(GoldenT5Buckets, RelativePositionBucketsMatchTransformers) {
  // Values of transformers' _relative_position_bucket(bidirectional=True, 32 buckets, max_distance 128).
  using dvs::models::t5_relative_position_bucket;
  EXPECT_EQ(t5_relative_position_bucket(0, true, 32, 128), 0);
  EXPECT_EQ(t5_relative_position_bucket(1, true, 32, 128), 17);
  EXPECT_EQ(t5_relative_position_bucket(-1, true, 32, 128), 1);
  EXPECT_EQ(t5_relative_position_bucket(-7, true, 32, 128), 7);
  EXPECT_EQ(t5_relative_position_bucket(-8, true, 32, 128), 8);    // first log bucket: 8 + int(0)
  EXPECT_EQ(t5_relative_position_bucket(-16, true, 32, 128), 10);  // 8 + log(2)/log(16)*8 = 10
  EXPECT_EQ(t5_relative_position_bucket(-127, true, 32, 128), 15);
  EXPECT_EQ(t5_relative_position_bucket(-500, true, 32, 128), 15);  // clamped
  EXPECT_EQ(t5_relative_position_bucket(225, true, 32, 128), 31);
  EXPECT_EQ(t5_relative_position_bucket(20, true, 32, 128), 16 + 8 + 2);  // log(2.5)/log(16)*8 = 2.64
}

TEST_F(GoldenT5, MaskedWithPerLayerHiddenStates) {
  dvs::models::T5Encoder t5(ctx(), pack() / "model" / "text_encoder");
  const auto ids = id_rows(pack_npy("t5/masked_input_ids.npy"));
  const auto mask_t = pack_npy("t5/masked_attention_mask.npy").to_f32();
  std::vector<std::vector<float>> mask(ids.size());
  for (size_t b = 0; b < ids.size(); ++b)
    mask[b].assign(mask_t.begin() + long(b * ids[b].size()), mask_t.begin() + long((b + 1) * ids[b].size()));
  std::vector<HostTensor> hidden;
  const dvs::Tensor out = t5.encode(ids, mask, &hidden);
  expect_close("t5_masked last_hidden_state", out.download(ctx()), "t5/masked_last_hidden_state.npy",
               pack_tolerance("t5_masked"));
  const Tol layers = pack_tolerance("t5_masked_layers");
  ASSERT_EQ(int64_t(hidden.size()), t5.config().num_layers + 1);
  for (size_t i = 0; i < hidden.size(); ++i) {
    const std::string rel = "t5/masked_hidden_state_" + std::to_string(i) + ".npy";
    ASSERT_TRUE(fs::exists(pack() / rel)) << "the pack has no hidden state " << i << ": " << pack() / rel;
    expect_close("t5_masked_layers hidden_states[" + std::to_string(i) + "]", hidden[i], rel, layers);
  }
}

TEST_F(GoldenT5, NoMask) {
  dvs::models::T5Encoder t5(ctx(), pack() / "model" / "text_encoder");
  const dvs::Tensor out = t5.encode(id_rows(pack_npy("t5/masked_input_ids.npy")));
  expect_close("t5_nomask", out.download(ctx()), "t5/nomask_last_hidden_state.npy", pack_tolerance("t5_nomask"));
}

TEST_F(GoldenT5, TextToEmbeddings) {
  const fs::path model = pack() / "model";
  const dvs::T5Tokenizer tok = dvs::T5Tokenizer::load(model);
  std::ifstream f(pack() / "tokenizer" / "prompts.json");
  const auto prompts = nlohmann::json::parse(f).get<std::vector<std::string>>();
  dvs::models::T5Encoder t5(ctx(), model / "text_encoder");
  const dvs::Tensor out = t5.encode_prompts(tok, {prompts.at(0)}, dvs::max_text_seq_length(model));
  expect_close("t5_text_to_embeddings", out.download(ctx()), "t5/text_embeds.npy",
               pack_tolerance("t5_text_to_embeddings"));
}

// The three e2e prompts in ONE batch of 3 rows (batching must not mix rows).
TEST_F(GoldenT5, E2EPromptsAsOneBatch) {
  dvs::models::T5Encoder t5(ctx(), pack() / "model" / "text_encoder");
  const char* names[3] = {"prompt", "negative", "empty"};
  std::vector<std::vector<int32_t>> ids;
  for (const char* n : names) ids.push_back(id_rows(pack_npy(std::string("e2e/") + n + "_input_ids.npy")).at(0));
  const dvs::Tensor out = t5.encode(ids);
  const HostTensor v = out.download(ctx());
  const Tol tol = pack_tolerance("t5_e2e_prompts");
  for (size_t i = 0; i < 3; ++i)
    expect_close(std::string("t5_e2e_prompts ") + names[i], v,
                 std::string("e2e/") + names[i] + "_embeds.npy", tol, int64_t(i));
}

TEST_F(GoldenT5, Bf16Sharded) {
  dvs::models::T5Encoder t5(ctx(), pack() / "model_bf16" / "text_encoder");
  EXPECT_EQ(t5.weights().get("shared.weight").dtype(), dvs::DType::bf16);
  const dvs::Tensor out = t5.encode(id_rows(pack_npy("t5/masked_input_ids.npy")));
  expect_close("bf16_sharded t5", out.download(ctx()), "bf16_sharded/t5_nomask_last_hidden_state.npy",
               pack_tolerance("bf16_sharded", "t5"));
}

// Not asserted: encode time at the pack's size (recording included, as a caller sees it).
TEST_F(GoldenT5, EncodeTimeAtPackSize) {
  dvs::models::T5Encoder t5(ctx(), pack() / "model" / "text_encoder");
  const auto ids = id_rows(pack_npy("t5/masked_input_ids.npy"));
  t5.encode(ids);  // warm-up
  const int reps = 3;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < reps; ++i) t5.encode(ids);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / reps;
  std::cout << "[timing] T5 encode " << ids.size() << "x" << ids[0].size() << " tokens: " << ms << " ms per call ("
            << ctx().caps().name << ")\n";
}
