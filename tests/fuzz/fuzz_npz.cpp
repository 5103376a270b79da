// A depth .npz as --depth reads it (io/depth.hpp load_depth): the zip archive through libzip, the member chosen
// ("depths" or the only array), its .npy bytes, then the checks and the disparity conversion.
#include "dvs/error.hpp"
#include "harness_input.hpp"
#include "io/depth.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = dvs::fuzz::write_scratch("depth.npz", dvs::fuzz::as_text(data, size));
  try {
    (void)dvs::load_depth(file);
  } catch (const dvs::Error&) {
  }
  return 0;
}
