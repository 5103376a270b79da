#include "prompt_length.hpp"

#include "dvs/error.hpp"
#include "models/cogvideox/tokenizer.hpp"

namespace dvs::cli {

std::optional<std::string> prompt_truncation_warning(const std::filesystem::path& model, const std::string& prompt,
                                                     const std::string& option) {
  if (prompt.empty()) return std::nullopt;
  try {
    const int max_len = max_text_seq_length(model);
    const T5Tokenizer tok = T5Tokenizer::load(model);
    const size_t tokens = tok.encode(prompt).size();  // with </s>
    if (tokens <= size_t(max_len)) return std::nullopt;
    return "warning: " + option + " is " + std::to_string(tokens) + " tokens but this model reads " +
           std::to_string(max_len) + " (max_text_seq_length, </s> included): the last " +
           std::to_string(tokens - size_t(max_len)) + " tokens are cut, as the reference pipeline does";
  } catch (const Error&) {
    return std::nullopt;
  }
}

}  // namespace dvs::cli
