// dvs/lora.hpp on the LoRA file reader's own argument rule (io/lora_file), its complaints as usage errors.
#include "dvs/lora.hpp"

#include <cmath>

#include "io/public_call.hpp"
#include "dvs/usage_error.hpp"
#include "io/lora_file.hpp"
#include "io/option_names.hpp"

namespace dvs {

LoraArgument parse_lora_argument(const std::string& spec) {
  return public_call("dvs::parse_lora_argument", [&]() -> LoraArgument {
    LoraSpec s;
    try {
      s = parse_lora_spec(spec);
    } catch (const UsageError&) {
      throw;
    } catch (const Error& e) {
      throw UsageError(e.what());
    }
    if (!std::isfinite(s.scale)) throw UsageError(option_name("RunOptions::lora") + " " + spec + ": the scale must be a finite number");
    return {s.file, s.scale};
  });
}

}  // namespace dvs
