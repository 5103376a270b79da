#include "pipeline/prompt_cut.hpp"

#include "io/option_names.hpp"

namespace dvs {

std::vector<std::string> prompt_cut_warnings(const RunOptions& o, const T5Tokenizer& tokenizer, int text_len) {
  std::vector<std::string> out;
  // Only what the user wrote: the official preset's own negative text is not the user's to shorten.
  for (const auto& [text, field] : {std::pair{&o.prompt, "RunOptions::prompt"},
                                    std::pair{&o.negative_prompt, "RunOptions::negative_prompt"}}) {
    if (text->empty()) continue;
    const size_t tokens = tokenizer.encode(*text).size(), model_max = size_t(text_len);  // with </s>
    if (tokens <= model_max) continue;
    out.push_back(option_name(field) + " is " + std::to_string(tokens) + " tokens but this model reads " +
                  std::to_string(model_max) + " (max_text_seq_length, </s> included): the last " +
                  std::to_string(tokens - model_max) + " tokens are cut, as the reference pipeline does");
  }
  return out;
}

}  // namespace dvs
