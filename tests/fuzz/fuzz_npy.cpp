// The .npy parser (io/npy.hpp) on bytes in memory: magic, version, header dict (descr, fortran_order, shape),
// the data size against the shape, and the conversions (f8 -> f32, i8 -> i32 with its range check, u2 -> i32).
#include "dvs/error.hpp"
#include "harness_input.hpp"
#include "io/npy.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  try {
    (void)dvs::parse_npy({data, size}, "fuzz.npy");
  } catch (const dvs::Error&) {
  }
  return 0;
}
