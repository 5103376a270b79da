#include "vk/limit_profiles.hpp"

#include <cctype>

#include "dvs/error.hpp"

namespace dvs::vk {

namespace {
constexpr uint64_t KiB = 1024, MiB = KiB * 1024, GiB = MiB * 1024;
constexpr uint32_t kU32 = 0xFFFFFFFFu;
constexpr double GB = 1e9, TFLOPS = 1e12;
}  // namespace

// One row per driver family. The figures are what such a device reports (vulkan.gpuinfo.org's reports for
// the named device, or the driver's source where it sets them as constants); a real device may differ:
// `dvs info` shows its own, `dvs plan --device` plans with them.
const std::vector<LimitProfile>& limit_profiles() {
  static const std::vector<LimitProfile> rows = {
      // Mesa lavapipe 22.3 (Debian 12), as `dvs info` reports it here: 2^27-byte bindings and texel views,
      // 2 GiB allocations; a CPU device allocates host RAM, so the budget is the machine's free RAM (16 GiB assumed).
      {"lavapipe", "Mesa lavapipe (llvmpipe, CPU)", 128 * MiB, 1u << 27, 2 * GiB, {65535, 65535, 65535}, 16, 16 * GiB,
       "Mesa 22.3 lavapipe as reported by `dvs info` (lp_limits: 2^27 binding/texels, 2 GiB allocation)",
       // Uploads are memcpy in RAM (~11 GB/s on the 2-core machine, docs/design.md §9); the fp32 FMA peak of
       // 2 threads (~105 GFLOP/s); one queue family.
       10 * GB, 0.1 * TFLOPS, false},
      // NVIDIA proprietary driver, GeForce RTX 4090 (24 GiB): storage bindings up to 2^32-1 bytes, texel views
      // 2^27 texels, allocations just under 4 GiB (0xFFE00000), 2^31-1 x 65535 x 65535 groups.
      {"nvidia", "NVIDIA GeForce RTX 4090, proprietary driver", kU32, 1u << 27, 0xFFE00000ull, {0x7FFFFFFF, 65535, 65535},
       16, 24 * GiB, "vulkan.gpuinfo.org reports of RTX 30/40-series on the proprietary driver (535+)",
       // PCIe 4.0 x16 pinned host -> device (~25 of 31.5 GB/s); Ada whitepaper: 165 TFLOP/s dense FP16 with FP32
       // accumulate; the driver exposes transfer-only families (copy engines).
       25 * GB, 165 * TFLOPS, true},
      // AMD Radeon RX 7900 XTX (24 GiB) on Mesa RADV: UINT32_MAX bindings and texel views, allocations of
      // 0xFFFFFFFC bytes (RADV_MAX_MEMORY_ALLOCATION_SIZE), UINT32_MAX x 65535 x 65535 groups.
      {"amd", "AMD Radeon RX 7900 XTX, Mesa RADV", kU32, kU32, 0xFFFFFFFCull, {kU32, 65535, 65535}, 4, 24 * GiB,
       "vulkan.gpuinfo.org reports of RDNA2/3 on RADV; the constants in Mesa's radv_physical_device.c",
       // PCIe 4.0 x16; AMD's specification: 122.8 TFLOP/s peak FP16; RADV hides its SDMA transfer queue unless
       // RADV_PERFTEST=transfer_queue, so uploads share the compute queue.
       25 * GB, 122.8 * TFLOPS, false},
      // Intel Arc A770 (16 GiB) on Mesa ANV: 1 GiB bindings (isl's max buffer size on older releases),
      // 2^27 texel views, 4 GiB allocations, 65535 groups per axis.
      {"intel", "Intel Arc A770, Mesa ANV", 1 * GiB, 1u << 27, 4 * GiB, {65535, 65535, 65535}, 64, 16 * GiB,
       "vulkan.gpuinfo.org reports of Arc A-series on ANV (Mesa 23); conservative where releases differ",
       // PCIe 4.0 x16; Intel's specification: 138 TFLOP/s FP16 on the XMX engines; conservative: no copy-engine
       // queue (ANV exposes one only on some releases).
       25 * GB, 138 * TFLOPS, false},
      // Apple M2 Pro (16 GiB unified) on MoltenVK: 4 GiB-1 bindings, 2^26 texel views (Metal's texture buffer
      // width), allocations up to Metal's maxBufferLength (~8 GiB at 16 GiB), budget Metal's
      // recommendedMaxWorkingSetSize (about 2/3 of RAM).
      {"apple", "Apple M2 Pro 16 GiB, MoltenVK", kU32, 1u << 26, 8 * GiB, {kU32, 65535, 65535}, 16, 10 * GiB + 640 * MiB,
       "vulkan.gpuinfo.org reports of Apple M-series on MoltenVK 1.2; Metal feature set tables",
       // Unified memory: an upload is a copy within the 200 GB/s of LPDDR5 (read + write, ~100 GB/s); the 19-core
       // GPU's ~6.8 TFLOP/s; MoltenVK exposes one queue family.
       100 * GB, 6.8 * TFLOPS, false},
      // The Vulkan specification's required minimums (Required Limits table): maxStorageBufferRange 2^27,
      // maxTexelBufferElements 65536, maxComputeWorkGroupCount 65535; maxMemoryAllocationSize 2^30 (Vulkan
      // 1.1, VkPhysicalDeviceMaintenance3Properties); minStorageBufferOffsetAlignment at most 256. The spec has
      // no memory minimum: 8 GiB, a small discrete GPU, is assumed.
      {"min", "any conformant Vulkan 1.1 device (the specification's minimums)", 1u << 27, 65536, 1 * GiB,
       {65535, 65535, 65535}, 256, 8 * GiB, "Vulkan specification, Required Limits table; Vulkan 1.1 Maintenance3",
       // Assumed: an 8 GiB card on PCIe 3.0 x16 (~12 GB/s pinned), no transfer-only queue, and no faster than
       // the fastest GPU of this table (165 TFLOP/s): an upload that hides there hides on any slower device.
       12 * GB, 165 * TFLOPS, false},
  };
  return rows;
}

std::string limit_profile_names() {
  std::string s;
  for (const auto& p : limit_profiles()) s += (s.empty() ? "" : ", ") + p.name;
  return s;
}

const LimitProfile& limit_profile(std::string_view name) {
  std::string lower(name);
  for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
  for (const auto& p : limit_profiles())
    if (p.name == lower) return p;
  throw Error("no limit profile named '" + std::string(name) + "' (profiles: " + limit_profile_names() + ")");
}

}  // namespace dvs::vk
