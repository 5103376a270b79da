// A prompt longer than the model's text length (transformer/config.json's max_text_seq_length, 226 tokens with </s>
// for CogVideoX-5B-I2V) is cut, as the reference pipeline does; the user is told, naming the option: the run logs
// it (dvs/logs.hpp), the preflight lists it among its notes.
#pragma once
#include <string>
#include <vector>

#include "dvs/pipeline.hpp"
#include "models/cogvideox/tokenizer.hpp"

namespace dvs {

// One warning per prompt the user gave (prompt, negative_prompt) that the model cuts; none when they fit.
std::vector<std::string> prompt_cut_warnings(const RunOptions& o, const T5Tokenizer& tokenizer, int text_len);

}  // namespace dvs
