// T5 tokenizer unit tests: special-token handling, truncation and padding rules, and clear errors for a
// missing or corrupt spiece.model. Uses the SentencePiece model of pack A (tests/golden/A/model).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/files.hpp"
#include "support/source_dir.hpp"
#include "dvs/error.hpp"
#include "models/cogvideox/tokenizer.hpp"

namespace fs = std::filesystem;

// A temporary model folder with an empty tokenizer/ inside.
struct TokenizerDir : dvs::test::TempDir {
  TokenizerDir() { std::filesystem::create_directories(path / "tokenizer"); }
};

namespace {

// The in-repo pack A (not DVS_GOLDEN_DIR): these expectations are about its tiny vocabulary.
fs::path model_dir() { return dvs::test::source_dir() / "tests/golden/A/model"; }

using dvs::test::error_of;

const dvs::T5Tokenizer& tok() {
  static dvs::T5Tokenizer t = dvs::T5Tokenizer::load(model_dir());
  return t;
}

}  // namespace

TEST(T5Tokenizer, SpecialIds) {
  EXPECT_EQ(tok().pad_id(), 0);
  EXPECT_EQ(tok().eos_id(), 1);
  EXPECT_EQ(tok().unk_id(), 2);
  EXPECT_EQ(tok().id_to_piece(1), "</s>");
  EXPECT_EQ(tok().id_to_piece(0), "<pad>");
  EXPECT_GE(tok().vocab_size(), 3);
}

TEST(T5Tokenizer, LoadsFromTokenizerFolderToo) {
  const dvs::T5Tokenizer t = dvs::T5Tokenizer::load(model_dir() / "tokenizer");
  EXPECT_EQ(t.encode("a red fox"), tok().encode("a red fox"));
}

TEST(T5Tokenizer, EmptyPrompt) {
  EXPECT_EQ(tok().encode(""), (std::vector<int32_t>{1}));
  EXPECT_EQ(tok().encode_padded("", 6), (std::vector<int32_t>{1, 0, 0, 0, 0, 0}));
  EXPECT_EQ(tok().encode("   "), (std::vector<int32_t>{1}));
}

TEST(T5Tokenizer, TruncationKeepsEos) {
  const std::string p = "The camera slowly orbits around the old lighthouse as waves crash against the rocks.";
  const auto full = tok().encode(p);
  ASSERT_GT(full.size(), 10u);
  for (int L : {1, 2, 5, 10}) {
    const auto ids = tok().encode_padded(p, L);
    ASSERT_EQ(ids.size(), size_t(L));
    EXPECT_EQ(ids.back(), 1) << L;
    EXPECT_TRUE(std::equal(ids.begin(), ids.end() - 1, full.begin())) << L;
  }
  // Long enough: identical to the un-padded ids followed by pads.
  const auto padded = tok().encode_padded(p, int(full.size()) + 3);
  EXPECT_TRUE(std::equal(full.begin(), full.end(), padded.begin()));
  EXPECT_EQ(padded[full.size()], 0);
  EXPECT_EQ(padded.back(), 0);
}

TEST(T5Tokenizer, WhitespaceIsCollapsed) {
  EXPECT_EQ(tok().encode("slow   zoom    in"), tok().encode("slow zoom in"));
  EXPECT_EQ(tok().encode("   a slow zoom in   "), tok().encode("a slow zoom in"));
}

TEST(T5Tokenizer, AddedTokensInTextAreKept) {
  // A literal </s> in the text is the special token itself; T5 adds no second </s> after it.
  auto ids = tok().encode("a red fox</s>");
  EXPECT_EQ(ids, tok().encode("a red fox"));
  // In the middle it splits the text: encode(a) + </s> + encode(b).
  auto a = tok().encode("a red"), b = tok().encode("fox");
  a.pop_back();
  std::vector<int32_t> expect = a;
  expect.push_back(1);
  expect.insert(expect.end(), b.begin(), b.end());
  EXPECT_EQ(tok().encode("a red</s>fox"), expect);
  EXPECT_EQ(tok().encode("<pad>"), (std::vector<int32_t>{0, 1}));
}

TEST(T5Tokenizer, UnknownCharactersGiveUnk) {
  const auto ids = tok().encode("\xe4\xb8\xad");  // a CJK character the tiny vocabulary lacks
  EXPECT_NE(std::find(ids.begin(), ids.end(), 2), ids.end());
}

TEST(T5Tokenizer, BadArguments) {
  EXPECT_NE(error_of([] { tok().encode_padded("x", 0); }).find("max_length"), std::string::npos);
  EXPECT_NE(error_of([] { tok().id_to_piece(1 << 20); }).find("outside the vocabulary"), std::string::npos);
}

TEST(T5Tokenizer, MissingModelNamesTheFile) {
  TokenizerDir d;
  const std::string msg = error_of([&] { dvs::T5Tokenizer::load(d.path); });
  EXPECT_NE(msg.find("spiece.model"), std::string::npos) << msg;
  EXPECT_NE(msg.find("not found"), std::string::npos) << msg;
}

TEST(T5Tokenizer, CorruptModelNamesTheFile) {
  TokenizerDir d;
  const fs::path file = d.path / "tokenizer" / "spiece.model";
  {
    std::ofstream f(file, std::ios::binary);
    f << "this is not a sentencepiece model \x01\x02\x03";
  }
  std::string msg = error_of([&] { dvs::T5Tokenizer::load(d.path); });
  EXPECT_NE(msg.find(file.string()), std::string::npos) << msg;
  {
    std::ofstream f(file, std::ios::binary | std::ios::trunc);
  }
  msg = error_of([&] { dvs::T5Tokenizer::load(d.path); });
  EXPECT_NE(msg.find(file.string()), std::string::npos) << msg;
  EXPECT_NE(msg.find("empty"), std::string::npos) << msg;
  {  // a truncated copy of the real model
    std::ifstream in(model_dir() / "tokenizer" / "spiece.model", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream f(file, std::ios::binary | std::ios::trunc);
    f.write(bytes.data(), std::streamsize(bytes.size() / 3));
  }
  msg = error_of([&] { dvs::T5Tokenizer::load(d.path); });
  EXPECT_NE(msg.find(file.string()), std::string::npos) << msg;
}

TEST(T5Tokenizer, CorruptConfigNamesTheFile) {
  TokenizerDir d;
  fs::copy_file(model_dir() / "tokenizer" / "spiece.model", d.path / "tokenizer" / "spiece.model");
  {
    std::ofstream f(d.path / "tokenizer" / "tokenizer_config.json");
    f << "{ not json";
  }
  const std::string msg = error_of([&] { dvs::T5Tokenizer::load(d.path); });
  EXPECT_NE(msg.find("tokenizer_config.json"), std::string::npos) << msg;
}

TEST(T5Tokenizer, WithoutConfigUsesT5Defaults) {
  TokenizerDir d;
  fs::copy_file(model_dir() / "tokenizer" / "spiece.model", d.path / "tokenizer" / "spiece.model");
  const dvs::T5Tokenizer t = dvs::T5Tokenizer::load(d.path);
  EXPECT_EQ(t.eos_id(), 1);
  EXPECT_EQ(t.pad_id(), 0);
  EXPECT_EQ(t.encode("a red fox</s>"), tok().encode("a red fox"));
}

TEST(T5Tokenizer, MaxTextSeqLength) {
  EXPECT_EQ(dvs::max_text_seq_length(model_dir()), 8);
  TokenizerDir d;
  const std::string msg = error_of([&] { dvs::max_text_seq_length(d.path); });
  EXPECT_NE(msg.find("config.json"), std::string::npos) << msg;
}
