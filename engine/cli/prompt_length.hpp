// A prompt longer than the model's text length (transformer/config.json's max_text_seq_length, 226 tokens
// with </s> for CogVideoX-5B-I2V) is cut, as the reference pipeline does; the user is told before the run.
#pragma once
#include <filesystem>
#include <optional>
#include <string>

namespace dvs::cli {

// The warning for `prompt` given as `option` ("--prompt"), or nothing when it fits. Loads the model's
// tokenizer; a model folder that cannot be read gives nothing here (the run reports it properly).
std::optional<std::string> prompt_truncation_warning(const std::filesystem::path& model, const std::string& prompt,
                                                     const std::string& option);

}  // namespace dvs::cli
