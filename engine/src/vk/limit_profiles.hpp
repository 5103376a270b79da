// Typical device limits of the common Vulkan driver families, for planning a run on a device that is not
// here (`dvs plan --limits NAME`). Each row cites where its numbers come from; `dvs info` shows a real
// device's own values, which `dvs plan --device` reads instead.
#pragma once
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace dvs::vk {

struct LimitProfile {
  std::string name;         // "lavapipe", "nvidia", "amd", "intel", "apple", "min"
  std::string describes;    // the device and driver the numbers are typical of
  uint64_t binding = 0;     // maxStorageBufferRange, bytes
  uint64_t texels = 0;      // maxTexelBufferElements
  uint64_t alloc = 0;       // maxMemoryAllocationSize, bytes
  uint32_t groups[3] = {};  // maxComputeWorkGroupCount x, y, z
  uint64_t alignment = 0;   // minStorageBufferOffsetAlignment, bytes
  uint64_t heap = 0;        // default --budget: the device-local memory such a device has
  std::string source;       // where the numbers come from
  // For weight streaming (dvs plan): the host -> device copy rate of pinned memory, the device's peak 16-bit
  // matrix rate with fp32 accumulation (what a block's compute cannot beat), and whether such a device has a
  // transfer-only queue family (copies beside the compute) -- typical figures, with sources in the table.
  double upload_bytes_per_second = 0;
  double peak_flops = 0;
  bool transfer_queue = false;
};

const std::vector<LimitProfile>& limit_profiles();
// The profile called `name` (case-insensitive); throws dvs::UsageError listing the names otherwise.
const LimitProfile& limit_profile(std::string_view name);
std::string limit_profile_names();  // "lavapipe, nvidia, amd, intel, apple, min"

}  // namespace dvs::vk
