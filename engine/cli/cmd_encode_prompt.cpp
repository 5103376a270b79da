// `dvs encode-prompt`: T5 embeddings of one prompt, exactly as the pipeline computes them.
#include <iostream>

#include "args.hpp"
#include "commands.hpp"
#include "dvs/pipeline.hpp"
#include "options.hpp"
#include "prompt_length.hpp"

namespace dvs::cli {

int run_encode_prompt(const std::vector<std::string>& argv) {
  Args a("encode-prompt",
         {"dvs encode-prompt --model DIR --prompt TEXT --out FILE.npy [--device I|NAME]",
          "Tokenizes TEXT (padded to the transformer's max_text_seq_length, 226 for CogVideoX-5B-I2V) and runs\n"
          "the model's T5 encoder as dvs run does (no attention mask). Writes [1, L, D] float32 (.npy).\n"
          "--prompt \"\" gives the embedding the inversion uses.\n",
          ""},
         {{"encode", {option_in(kModelInputs, "model"), option_in(kPromptInputs, "prompt"),
                      {"out", "FILE.npy", "where the embeddings go ([1, L, D] float32)"}}},
          kDevice});
  a.parse(argv);
  if (a.help()) return 0;
  const std::filesystem::path model = a.required("model"), out = a.required("out");
  if (!a.has("prompt")) a.fail("--prompt is required (\"\" is allowed)");
  if (auto w = prompt_truncation_warning(model, a.str("prompt"), "--prompt")) std::cerr << "dvs encode-prompt: " << *w << "\n";
  const auto shape = encode_prompt(model, a.str("prompt"), out, a.str("device"));
  std::cout << "wrote " << out.string() << " [";
  for (size_t i = 0; i < shape.size(); ++i) std::cout << (i ? "," : "") << shape[i];
  std::cout << "]\n";
  return 0;
}

}  // namespace dvs::cli
