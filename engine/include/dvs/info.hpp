// Device listing for `dvs info` and for applications that let a user choose a GPU.
#pragma once
#include <cstdint>
#include <string>

#include "dvs/api.hpp"
#include "dvs/version.h"  // DVS_VERSION_MAJOR/MINOR/PATCH: the headers' version

namespace dvs {

// Every Vulkan device with its type, driver, Vulkan version, subgroup size, features and limits; marks
// the one that `device_spec` (index, name substring, or "" for the default/DVS_DEVICE) selects.
DVS_API std::string device_report(const std::string& device_spec = "");

// The library's version, "MAJOR.MINOR.PATCH" (the one loaded at run time; DVS_VERSION_* are the headers').
DVS_API const char* version();

// `dvs info --bench-upload`: how fast the device reads host memory, as streamed weights are uploaded (pinned host
// memory -> device-local, one copy per upload on the transfer queue, or the compute queue where there is none).
struct UploadBench {
  std::string device;
  std::string queue;             // "transfer-only family N" or "compute queue"
  uint64_t bytes = 0;            // per upload
  int uploads = 0;               // timed (after one untimed)
  double bytes_per_second = 0;   // the median upload's
  double min_bytes_per_second = 0, max_bytes_per_second = 0;
};
DVS_API UploadBench bench_upload(const std::string& device_spec = "", uint64_t bytes = 256ull << 20, int uploads = 5);

}  // namespace dvs
