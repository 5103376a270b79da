// How much device memory dvs may hold on a device, and where that figure comes from: the one place that
// reads heap sizes for planning and refusing allocations (the Allocator enforces it, `dvs info` shows it).
//
// Policy:
// - CPU devices (VK_PHYSICAL_DEVICE_TYPE_CPU, e.g. lavapipe): device memory is host RAM, and the reported heap
//   is a guess that is not a limit (Mesa 22.3 reports a fixed 2 GiB and allocates far beyond it; Mesa 25.0
//   reports MemTotal, budget included, whatever other processes hold). dvs plans against the host RAM
//   available when the device is opened (/proc/meminfo MemAvailable), falling back to the reported heap
//   where /proc/meminfo cannot be read.
// - GPUs with VK_EXT_memory_budget: the device-local heap's budget, re-read before every new memory block
//   (it moves with other processes' use), compared with the heap's usage by this process plus the request.
// - GPUs without it: the reported size of the device-local heap.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <optional>
#include <string>

namespace dvs::vk {

struct HostMemory {
  uint64_t total = 0;      // MemTotal
  uint64_t available = 0;  // MemAvailable
};

// Parses /proc/meminfo text ("MemAvailable:   21071932 kB"); nullopt when either field is missing.
std::optional<HostMemory> parse_meminfo(const std::string& text);
std::optional<HostMemory> read_host_memory();  // /proc/meminfo; nullopt where there is none (not Linux)

enum class MemoryBudgetSource { host_ram, heap_budget, heap_size };

struct DeviceMemoryBudget {
  uint64_t bytes = 0;          // dvs's device allocations (in the heap below) stay within this
  uint32_t heap = 0;           // the device-local heap dvs allocates device buffers from
  uint64_t reported_heap = 0;  // that heap's size as the driver reports it
  MemoryBudgetSource source = MemoryBudgetSource::heap_size;
  std::string describe() const;  // one line for `dvs info` and error messages
};

// The policy above on plain values (no Vulkan calls): `heap_budget` is VK_EXT_memory_budget's heapBudget
// for the heap, when the device has the extension; `host` is /proc/meminfo, when readable.
DeviceMemoryBudget decide_memory_budget(VkPhysicalDeviceType type, uint32_t heap, uint64_t heap_size,
                                        std::optional<uint64_t> heap_budget, std::optional<HostMemory> host);

// The device-local heap dvs allocates from: the largest device-local heap (the Allocator's choice).
uint32_t device_heap_index(const VkPhysicalDeviceMemoryProperties& mp);

// VK_EXT_memory_budget's (budget, usage by this process) for `heap`; nullopt without the extension.
struct HeapBudget { uint64_t budget = 0, usage = 0; };
std::optional<HeapBudget> query_heap_budget(VkPhysicalDevice pd, bool has_memory_budget_ext, uint32_t heap);

// decide_memory_budget() for a physical device, reading its heaps, budget and the host's memory now.
DeviceMemoryBudget query_memory_budget(VkPhysicalDevice pd, VkPhysicalDeviceType type, bool has_memory_budget_ext);

}  // namespace dvs::vk
