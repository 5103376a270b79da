// run.json as `dvs run --from` reads it (dvs/run_record.hpp run_record_arguments): every key turned back into
// dvs run arguments, then those matched against dvs run's options and read as RunOptions, as dvs run does next.
#include "dvs/error.hpp"
#include "dvs/run_record.hpp"
#include "harness_input.hpp"
#include "run_arguments.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = dvs::fuzz::write_scratch("run.json", dvs::fuzz::as_text(data, size));
  try {
    dvs::fuzz::check_run_arguments(dvs::run_record_arguments(file));
  } catch (const dvs::Error&) {
  }
  return 0;
}
