// dvs/prompt.hpp on the model's own tokenizer (models/cogvideox/tokenizer).
#include "dvs/prompt.hpp"

#include "io/public_call.hpp"
#include "models/cogvideox/tokenizer.hpp"

namespace dvs {

PromptLength prompt_length(const std::filesystem::path& model, const std::string& prompt) {
  return public_call("dvs::prompt_length", [&]() -> PromptLength {
    PromptLength n;
    n.model_max = size_t(max_text_seq_length(model));
    n.tokens = T5Tokenizer::load(model).encode(prompt).size();  // with </s>
    return n;
  });
}

}  // namespace dvs
