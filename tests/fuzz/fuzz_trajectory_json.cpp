// A JSON trajectory as --trajectory FILE.json reads it (geometry/trajectory_json.hpp through load_trajectory):
// convention, axes, relative_to_first, the poses (4x4 rows, 16 numbers or R/t) and the rigidity checks.
#include "dvs/error.hpp"
#include "geometry/trajectory.hpp"
#include "harness_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = dvs::fuzz::write_scratch("camera.json", dvs::fuzz::as_text(data, size));
  try {
    (void)dvs::geometry::load_trajectory(file.string(), 3, 1.0);
  } catch (const dvs::Error&) {
  }
  return 0;
}
