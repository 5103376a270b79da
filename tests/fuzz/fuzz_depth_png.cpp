// One frame of a PNG depth folder (io/depth_images.hpp read_depth_png): OpenCV decodes the PNG (libpng is not
// ours and not instrumented), dvs checks what it got (empty, channel count) and converts it to f32.
#include "dvs/error.hpp"
#include "harness_input.hpp"
#include "io/depth_images.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = dvs::fuzz::write_scratch("d_0001.png", dvs::fuzz::as_text(data, size));
  try {
    (void)dvs::read_depth_png(file);
  } catch (const dvs::Error&) {
  }
  return 0;
}
