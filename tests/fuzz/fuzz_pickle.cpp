// The restricted pickle reader (io/pickle_state_dict.hpp) on data.pkl bytes directly, so the fuzzer spends its
// time on opcodes rather than on the zip around them (fuzz_pth covers the archive).
#include "dvs/error.hpp"
#include "harness_input.hpp"
#include "io/pickle_state_dict.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    (void)dvs::parse_state_dict_pickle({data, size}, "fuzz.pth");
  } catch (const dvs::Error&) {
  }
  return 0;
}
