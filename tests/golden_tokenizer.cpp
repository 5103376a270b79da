// Golden check of the T5 tokenizer against the pack's `tokenizer` case: every prompt of
// tokenizer/prompts.json, padded (max_length = transformer max_text_seq_length, truncation) and un-padded,
// must give exactly the ids transformers' slow T5Tokenizer produced. Tolerance: exact.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "io/npy.hpp"
#include "models/cogvideox/tokenizer.hpp"
#include "support/gpu.hpp"

namespace fs = std::filesystem;

namespace {

fs::path pack() { return fs::path(dvs::test::golden_dir()); }

nlohmann::json load_json(const fs::path& p) {
  std::ifstream f(p);
  return nlohmann::json::parse(f);
}

std::vector<int32_t> ints(const dvs::HostTensor& t, size_t begin, size_t count) {
  const auto v = t.to_f32();
  std::vector<int32_t> out;
  for (size_t i = begin; i < begin + count; ++i) out.push_back(int32_t(v[i]));
  return out;
}

}  // namespace

TEST(GoldenTokenizer, PromptsPaddedAndUnpadded) {
  const fs::path model = pack() / "model";
  const dvs::T5Tokenizer tok = dvs::T5Tokenizer::load(model);
  const int max_length = dvs::max_text_seq_length(model);
  const auto prompts = load_json(pack() / "tokenizer" / "prompts.json").get<std::vector<std::string>>();
  const auto pieces = load_json(pack() / "tokenizer" / "pieces.json");
  const dvs::HostTensor padded = dvs::read_npy(pack() / "tokenizer" / "padded_input_ids.npy");
  ASSERT_EQ(padded.shape.size(), 2u);
  ASSERT_EQ(padded.shape[0], int64_t(prompts.size()));
  ASSERT_EQ(padded.shape[1], max_length);
  EXPECT_EQ(tok.eos_id(), 1);
  EXPECT_EQ(tok.pad_id(), 0);
  EXPECT_EQ(tok.unk_id(), 2);

  for (size_t i = 0; i < prompts.size(); ++i) {
    const std::string& p = prompts[i];
    EXPECT_EQ(tok.encode_padded(p, max_length), ints(padded, i * size_t(max_length), size_t(max_length)))
        << "padded ids of prompt " << i << " '" << p << "'";
    const dvs::HostTensor un = dvs::read_npy(pack() / "tokenizer" / ("unpadded_ids_" + std::to_string(i) + ".npy"));
    const std::vector<int32_t> ids = tok.encode(p);
    EXPECT_EQ(ids, ints(un, 0, size_t(un.numel()))) << "un-padded ids of prompt " << i << " '" << p << "'";
    std::vector<std::string> ours;
    for (int32_t id : ids) ours.push_back(tok.id_to_piece(id));
    EXPECT_EQ(ours, pieces[i].get<std::vector<std::string>>()) << "pieces of prompt " << i;
  }
}

// t5_text_to_embeddings: its input ids are the tokenizer's row 0.
TEST(GoldenTokenizer, TextInputIdsOfT5Case) {
  const fs::path model = pack() / "model";
  const dvs::T5Tokenizer tok = dvs::T5Tokenizer::load(model);
  const auto prompts = load_json(pack() / "tokenizer" / "prompts.json").get<std::vector<std::string>>();
  const dvs::HostTensor ids = dvs::read_npy(pack() / "t5" / "text_input_ids.npy");
  EXPECT_EQ(tok.encode_padded(prompts.at(0), dvs::max_text_seq_length(model)), ints(ids, 0, size_t(ids.numel())));
  // The empty prompt of the e2e inversion: </s> then pads.
  const dvs::HostTensor empty = dvs::read_npy(pack() / "e2e" / "empty_input_ids.npy");
  EXPECT_EQ(tok.encode_padded("", dvs::max_text_seq_length(model)), ints(empty, 0, size_t(empty.numel())));
}
