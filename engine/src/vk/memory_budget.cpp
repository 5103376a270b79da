#include "vk/memory_budget.hpp"

#include <fstream>
#include <sstream>

#include "vk/memory.hpp"

namespace dvs::vk {

std::optional<HostMemory> parse_meminfo(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  std::optional<uint64_t> total, available;
  while (std::getline(in, line)) {
    std::istringstream f(line);
    std::string key, unit;
    uint64_t value = 0;
    if (!(f >> key >> value)) continue;
    f >> unit;
    uint64_t scale = unit == "kB" ? 1024 : 1;  // the kernel writes kB (KiB); a bare number is bytes
    if (key == "MemTotal:") total = value * scale;
    else if (key == "MemAvailable:") available = value * scale;
  }
  if (!total || !available) return std::nullopt;
  return HostMemory{*total, *available};
}

std::optional<HostMemory> read_host_memory() {
  std::ifstream f("/proc/meminfo");
  if (!f) return std::nullopt;
  std::stringstream s;
  s << f.rdbuf();
  return parse_meminfo(s.str());
}

DeviceMemoryBudget decide_memory_budget(VkPhysicalDeviceType type, uint32_t heap, uint64_t heap_size,
                                        std::optional<uint64_t> heap_budget, std::optional<HostMemory> host) {
  DeviceMemoryBudget b;
  b.heap = heap;
  b.reported_heap = heap_size;
  if (type == VK_PHYSICAL_DEVICE_TYPE_CPU && host) {
    b.bytes = host->available;
    b.source = MemoryBudgetSource::host_ram;
  } else if (heap_budget) {
    b.bytes = *heap_budget;
    b.source = MemoryBudgetSource::heap_budget;
  } else {
    b.bytes = heap_size;
    b.source = MemoryBudgetSource::heap_size;
  }
  return b;
}

std::string DeviceMemoryBudget::describe() const {
  std::string s = format_bytes(bytes) + " (";
  switch (source) {
    case MemoryBudgetSource::host_ram:
      s += "CPU device: host RAM available, /proc/meminfo MemAvailable; the reported heap " + std::to_string(heap) +
           " of " + format_bytes(reported_heap) + " is not a limit here";
      break;
    case MemoryBudgetSource::heap_budget:
      s += "VK_EXT_memory_budget heapBudget of heap " + std::to_string(heap) + ", which reports " +
           format_bytes(reported_heap);
      break;
    case MemoryBudgetSource::heap_size:
      s += "reported size of heap " + std::to_string(heap);
      break;
  }
  return s + ")";
}

uint32_t device_heap_index(const VkPhysicalDeviceMemoryProperties& mp) {
  VkDeviceSize biggest = 0;
  uint32_t big_heap = 0;
  for (uint32_t h = 0; h < mp.memoryHeapCount; ++h)
    if ((mp.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT) && mp.memoryHeaps[h].size > biggest) {
      biggest = mp.memoryHeaps[h].size;
      big_heap = h;
    }
  return big_heap;
}

std::optional<HeapBudget> query_heap_budget(VkPhysicalDevice pd, bool has_memory_budget_ext, uint32_t heap) {
  if (!has_memory_budget_ext) return std::nullopt;
  VkPhysicalDeviceMemoryBudgetPropertiesEXT budget{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MEMORY_BUDGET_PROPERTIES_EXT};
  VkPhysicalDeviceMemoryProperties2 mp2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MEMORY_PROPERTIES_2};
  mp2.pNext = &budget;
  vkGetPhysicalDeviceMemoryProperties2(pd, &mp2);
  if (heap >= mp2.memoryProperties.memoryHeapCount || budget.heapBudget[heap] == 0) return std::nullopt;
  return HeapBudget{budget.heapBudget[heap], budget.heapUsage[heap]};
}

DeviceMemoryBudget query_memory_budget(VkPhysicalDevice pd, VkPhysicalDeviceType type, bool has_memory_budget_ext) {
  VkPhysicalDeviceMemoryProperties mp{};
  vkGetPhysicalDeviceMemoryProperties(pd, &mp);
  uint32_t heap = device_heap_index(mp);
  std::optional<uint64_t> budget;
  if (auto hb = query_heap_budget(pd, has_memory_budget_ext, heap)) budget = hb->budget;
  std::optional<HostMemory> host;
  if (type == VK_PHYSICAL_DEVICE_TYPE_CPU) host = read_host_memory();
  return decide_memory_budget(type, heap, mp.memoryHeaps[heap].size, budget, host);
}

}  // namespace dvs::vk
