// The safetensors reader (io/safetensors.hpp): header length, JSON header, dtypes, shapes, data offsets, then
// every tensor's bytes and, for the engine's dtypes, a loaded copy (reads that open() promised stay in bounds).
#include "dvs/error.hpp"
#include "harness_input.hpp"
#include "io/safetensors.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = dvs::fuzz::write_scratch("model.safetensors", dvs::fuzz::as_text(data, size));
  try {
    const dvs::SafetensorsFile f = dvs::SafetensorsFile::open(file);
    for (const dvs::TensorInfo& t : f.tensors()) {
      (void)f.bytes(t);
      if (t.dtype) (void)f.load(t);
    }
  } catch (const dvs::Error&) {
  }
  return 0;
}
