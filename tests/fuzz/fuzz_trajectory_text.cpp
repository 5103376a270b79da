// An official-format trajectory file (three lines of numbers) as --trajectory FILE reads it
// (geometry/trajectory.hpp load_trajectory): the text check, the parser, then the interpolation to 49 frames.
#include "dvs/error.hpp"
#include "geometry/trajectory.hpp"
#include "harness_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = dvs::fuzz::write_scratch("camera.txt", dvs::fuzz::as_text(data, size));
  try {
    (void)dvs::geometry::load_trajectory(file.string(), 49, 1.0);
  } catch (const dvs::Error&) {
  }
  return 0;
}
