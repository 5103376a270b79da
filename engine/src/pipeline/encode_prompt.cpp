// `dvs encode-prompt`: the pipeline's text stage alone.
#include <cerrno>

#include "dvs/error.hpp"
#include "dvs/pipeline.hpp"
#include "io/npy.hpp"
#include "io/option_names.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/cogvideox/tokenizer.hpp"
#include "vk/context.hpp"

namespace dvs {

std::vector<int64_t> encode_prompt(const std::filesystem::path& model, const std::string& prompt,
                                   const std::filesystem::path& out_npy, const std::string& device) {
  if (!std::filesystem::is_directory(model))
    throw Error(model.string() + ": no such model folder (" +
                in_words_of_caller("give --model DIR", "the model argument must be a folder") +
                " laid out like THUDM/CogVideoX-5b-I2V)");
  // The output is checked before the T5 encoder runs (minutes for the real one), naming the user's path.
  if (!out_npy.parent_path().empty() && !std::filesystem::is_directory(out_npy.parent_path()))
    throw Error(out_npy.string() + ": " + cannot_create_note(out_npy, ENOENT) + " (create it, or give another " +
                in_words_of_caller("--out", "output path") + ")");
  if (std::filesystem::is_directory(out_npy)) throw Error(out_npy.string() + ": is a folder; give " +
                in_words_of_caller("--out FILE.npy", "a file path ending in .npy"));
  const T5Tokenizer tokenizer = T5Tokenizer::load(model);
  const int text_len = max_text_seq_length(model);
  vk::ContextOptions copt;
  copt.device = device;
  vk::Context ctx(copt);
  models::T5Encoder t5(ctx, model / "text_encoder");
  const Tensor text = t5.encode_prompts(tokenizer, {prompt}, text_len);  // [1, L, D]
  write_npy(out_npy, text.download(ctx));
  return text.shape();
}

}  // namespace dvs
