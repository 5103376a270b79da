// A PyTorch .pth checkpoint (io/pth_file.hpp): the zip archive, its data.pkl through the restricted pickle reader,
// every tensor checked against its storage record, then every tensor's bytes read (strided ones gathered).
#include "dvs/error.hpp"
#include "harness_input.hpp"
#include "io/pth_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = dvs::fuzz::write_scratch("model.pth", dvs::fuzz::as_text(data, size));
  try {
    const dvs::PthFile f = dvs::PthFile::open(file);
    for (const dvs::PthTensorInfo& t : f.tensors()) (void)f.read_bytes(t);
  } catch (const dvs::Error&) {
  }
  return 0;
}
