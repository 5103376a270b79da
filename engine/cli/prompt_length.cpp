#include "prompt_length.hpp"

#include "dvs/error.hpp"
#include "dvs/prompt.hpp"

namespace dvs::cli {

std::optional<std::string> prompt_truncation_warning(const std::filesystem::path& model, const std::string& prompt,
                                                     const std::string& option) {
  if (prompt.empty()) return std::nullopt;
  try {
    const PromptLength n = prompt_length(model, prompt);
    if (!n.truncated()) return std::nullopt;
    return "warning: " + option + " is " + std::to_string(n.tokens) + " tokens but this model reads " +
           std::to_string(n.model_max) + " (max_text_seq_length, </s> included): the last " +
           std::to_string(n.tokens - n.model_max) + " tokens are cut, as the reference pipeline does";
  } catch (const Error&) {
    return std::nullopt;
  }
}

}  // namespace dvs::cli
