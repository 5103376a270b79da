// A LoRA file as --lora reads it (io/lora_file.hpp): the weight file (safetensors or .pth, by content), the
// A/B pairs, their shapes and the optional alpha.
#include "dvs/error.hpp"
#include "harness_input.hpp"
#include "io/lora_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = dvs::fuzz::write_scratch("adapter.safetensors", dvs::fuzz::as_text(data, size));
  try {
    (void)dvs::read_lora_file(file, 1.0);
  } catch (const dvs::Error&) {
  }
  return 0;
}
