// The Vulkan devices dvs can run on and the limits a run is planned against: a device's own (as `dvs info`
// shows them) or a typical device of a driver family (a "limit profile", for planning a run on a device that
// is not here). DVS_LIMITS lowers both, as it lowers the device a run opens (see README, "DVS_LIMITS").
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "dvs/api.hpp"

namespace dvs {

// The four limits every op and allocation honours, the allocator's alignment and the memory dvs may hold.
struct DeviceLimits {
  std::string source;       // "device 0 (llvmpipe ...)", "profile nvidia (RTX 4090 ...)", plus " lowered by DVS_LIMITS"
  uint64_t binding = 0;     // maxStorageBufferRange, bytes
  uint64_t texels = 0;      // maxTexelBufferElements
  uint64_t alloc = 0;       // maxMemoryAllocationSize, bytes
  uint32_t groups = 0;      // maxComputeWorkGroupCount (x)
  uint64_t alignment = 0;   // minStorageBufferOffsetAlignment, bytes
  uint64_t memory = 0;      // device memory dvs may hold (the device's budget, or the profile's typical heap)
  // For weight streaming (0 / -1: not known; a profile's are typical figures, a device's are not measured here):
  double upload_bytes_per_second = 0;  // host -> device copy rate (dvs info --bench-upload measures a device's)
  double peak_flops = 0;               // the device's peak 16-bit matrix rate with fp32 accumulation
  int transfer_queue = -1;             // 1: a transfer-only queue family (copies beside the compute), 0: none
};

struct DeviceSummary {
  uint32_t index = 0;       // what --device I selects
  std::string name, type;   // "llvmpipe (LLVM 15.0.6, 256 bits)", "cpu" / "discrete GPU" / ...
  bool selected = false;    // the device `device_spec` (or DVS_DEVICE, or the default rule) picks
  DeviceLimits limits;
};

// Every Vulkan device; `device_spec` (an index, a name substring, or "" for DVS_DEVICE / the default) marks
// the selected one. Throws dvs::Error when there is no Vulkan device or nothing matches the spec.
DVS_API std::vector<DeviceSummary> list_devices(const std::string& device_spec = "");

// The limits of the device `device_spec` selects, lowered by DVS_LIMITS (the values a run on it plans against).
DVS_API DeviceLimits device_limits(const std::string& device_spec);

// A typical device of a driver family: "lavapipe", "nvidia", "amd", "intel", "apple" or "min" (the Vulkan
// specification's minimums), case-insensitive, lowered by DVS_LIMITS. Throws dvs::UsageError listing the names.
DVS_API DeviceLimits profile_limits(const std::string& profile);
DVS_API std::vector<std::string> limit_profile_names();

}  // namespace dvs
