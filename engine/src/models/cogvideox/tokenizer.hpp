// T5 tokenizer: what transformers' slow T5Tokenizer (legacy=True) does, as CogVideoX calls it.
//
// Encoding of one prompt:
//  1. The text is split around the tokenizer's added tokens (<pad>, </s>, <unk>, <extra_id_N>, ... from
//     tokenizer_config.json's added_tokens_decoder, or derived from extra_ids); an added token found in
//     the text becomes its own id (transformers' Trie split: earliest match, longest token at it).
//  2. Every other chunk is encoded by SentencePiece (tokenizer/spiece.model, libsentencepiece): its
//     normaliser (nmt_nfkc, whitespace trimming and collapsing, dummy-prefix U+2581) and its Viterbi
//     segmentation; unknown characters give <unk>.
//  3. `</s>` is appended unless the ids already end with it (T5Tokenizer._add_eos_if_not_present).
// Padded call (padding='max_length', truncation=True): the ids of step 2 are cut to max_length - 1
// before `</s>`, then right-padded with <pad> to max_length.
// CogVideoX's tokenizer_config.json says legacy=true; the non-legacy mode of newer transformers differs
// only in how text right after an added token is prefixed, and is not modelled.
#pragma once
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace dvs {

class T5Tokenizer {
 public:
  // `folder` is a model folder holding tokenizer/, or the tokenizer folder itself. Reads spiece.model
  // (required) and tokenizer_config.json (optional). Throws dvs::Error naming the file on a missing or
  // corrupt model.
  static T5Tokenizer load(const std::filesystem::path& folder);

  T5Tokenizer(T5Tokenizer&&) noexcept;
  T5Tokenizer& operator=(T5Tokenizer&&) noexcept;
  ~T5Tokenizer();

  // tokenizer(text).input_ids: no padding, no truncation, ends with </s>.
  std::vector<int32_t> encode(std::string_view text) const;

  // tokenizer([text], padding='max_length', max_length=max_length, truncation=True).input_ids[0]:
  // exactly max_length ids. max_length >= 1.
  std::vector<int32_t> encode_padded(std::string_view text, int max_length) const;

  int pad_id() const;
  int eos_id() const;
  int unk_id() const;
  int vocab_size() const;                    // SentencePiece pieces + added tokens beyond them
  std::string id_to_piece(int id) const;     // convert_ids_to_tokens for one id
  const std::filesystem::path& model_file() const;

 private:
  struct Impl;
  explicit T5Tokenizer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// transformer/config.json's max_text_seq_length of a model folder (226 for CogVideoX-5B-I2V): the
// length CogVideoX pads prompts to. Throws dvs::Error naming the file when it is missing or invalid.
int max_text_seq_length(const std::filesystem::path& model_folder);

}  // namespace dvs
