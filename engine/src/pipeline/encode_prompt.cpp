// `dvs encode-prompt`: the pipeline's text stage alone.
#include "dvs/error.hpp"
#include "dvs/pipeline.hpp"
#include "io/npy.hpp"
#include "models/cogvideox/t5_encoder.hpp"
#include "models/cogvideox/tokenizer.hpp"
#include "vk/context.hpp"

namespace dvs {

std::vector<int64_t> encode_prompt(const std::filesystem::path& model, const std::string& prompt,
                                   const std::filesystem::path& out_npy, const std::string& device) {
  if (!std::filesystem::is_directory(model))
    throw Error(model.string() + ": no such model folder (give --model DIR laid out like THUDM/CogVideoX-5b-I2V)");
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
