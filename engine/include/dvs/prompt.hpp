// Prompt length against the model's text length: a prompt longer than transformer/config.json's
// max_text_seq_length (226 tokens with </s> for CogVideoX-5B-I2V) is cut, as the reference pipeline does.
#pragma once
#include <cstddef>
#include <filesystem>
#include <string>

#include "dvs/api.hpp"

namespace dvs {

struct PromptLength {
  size_t tokens = 0;     // the prompt's T5 tokens, </s> included
  size_t model_max = 0;  // what the model reads (max_text_seq_length); tokens beyond it are cut
  bool truncated() const { return tokens > model_max; }
};

// Tokenizes `prompt` with the model folder's tokenizer. Throws dvs::Error naming the file when the model's
// tokenizer or transformer config cannot be read.
DVS_API PromptLength prompt_length(const std::filesystem::path& model, const std::string& prompt);

}  // namespace dvs
