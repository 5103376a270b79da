// Device memory: large VkDeviceMemory blocks (each ≤ maxMemoryAllocationSize, with one VkBuffer covering
// it) suballocated first-fit into Buffers. A Buffer may be larger than one descriptor binds
// (maxStorageBufferRange): ops that meet such a tensor bind bounded sub-ranges of it (Recorder::dispatch
// refuses any binding over the limit). A request larger than one allocation (maxMemoryAllocationSize) is
// refused with an error that says so.
#pragma once
#include <vulkan/vulkan.h>

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "vk/memory_budget.hpp"

namespace dvs::vk {

class Context;
class Allocator;

enum class MemoryUse {
  device,    // device-local; host-mapped too where the device is unified (lavapipe, integrated GPUs)
  upload,    // host-visible, coherent: staging towards the device
  readback,  // host-visible, coherent, cached where possible: staging back to the host
};

// A non-owning range of a VkBuffer. `mapped` points at `offset` when the memory is host-visible.
struct BufferView {
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceSize offset = 0;
  VkDeviceSize size = 0;
  uint8_t* mapped = nullptr;

  bool valid() const { return buffer != VK_NULL_HANDLE; }
  BufferView sub(VkDeviceSize off, VkDeviceSize bytes) const;  // throws when out of range
};

struct MemoryBlock {
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceSize size = 0;
  uint8_t* mapped = nullptr;
  MemoryUse use = MemoryUse::device;
  uint32_t heap = 0;         // memory heap of the allocation
  VkDeviceSize bytes = 0;    // allocation size (memory requirements: may exceed `size`)
  std::map<VkDeviceSize, VkDeviceSize> free_ranges;  // offset -> size, coalesced
};

// Owning handle to a suballocation; move-only, returns its range on destruction.
class Buffer {
 public:
  Buffer() = default;
  ~Buffer();
  Buffer(Buffer&& o) noexcept;
  Buffer& operator=(Buffer&& o) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;

  const BufferView& view() const { return view_; }
  VkDeviceSize size() const { return view_.size; }
  uint8_t* mapped() const { return view_.mapped; }
  bool valid() const { return view_.valid(); }

 private:
  friend class Allocator;
  Allocator* owner_ = nullptr;
  MemoryBlock* block_ = nullptr;
  VkDeviceSize reserved_ = 0;  // aligned size taken from the block
  BufferView view_;
};

struct MemoryStats {
  uint64_t bytes_in_use = 0;
  uint64_t peak_bytes_in_use = 0;
  uint64_t bytes_reserved = 0;  // in VkDeviceMemory blocks
  uint32_t blocks = 0;
};

class Allocator {
 public:
  explicit Allocator(Context& ctx);
  ~Allocator();

  // `what` names the request in error messages ("transformer weights", "attention scores", ...).
  Buffer allocate(VkDeviceSize bytes, MemoryUse use = MemoryUse::device, const std::string& what = "buffer");

  const MemoryStats& stats() const { return stats_; }
  VkDeviceSize alignment() const { return alignment_; }
  VkDeviceSize block_size() const { return block_size_; }
  bool device_memory_is_mapped() const;  // unified memory: uploads are plain memcpy
  VkDeviceSize max_binding() const;      // maxStorageBufferRange

  // Device memory this allocator may hold in the device heap (memory_budget.hpp: host RAM available on a CPU
  // device, the heap budget or size on a GPU); a new block beyond it is refused with an error naming the
  // request. The budget is read when the allocator is made (a GPU's heap budget again before every block).
  const DeviceMemoryBudget& memory_budget() const { return budget_; }
  uint64_t device_memory_capacity() const;        // the budget, lowered by limit_device_memory()
  uint64_t device_memory_reserved() const { return heap_reserved_; }
  void limit_device_memory(uint64_t bytes);       // a lower cap (tests; sharing a device)

 private:
  friend class Buffer;
  void release(Buffer& b);
  MemoryBlock* new_block(VkDeviceSize size, MemoryUse use, const std::string& what);
  uint32_t memory_type_for(MemoryUse use, uint32_t type_bits) const;
  void check_budget(VkDeviceSize size, uint32_t heap, const std::string& what) const;  // throws when over

  Context& ctx_;
  VkDeviceSize alignment_ = 256;
  VkDeviceSize block_size_ = 0;
  std::vector<std::unique_ptr<MemoryBlock>> blocks_;
  MemoryStats stats_;
  DeviceMemoryBudget budget_;
  std::optional<uint64_t> limit_;
  uint64_t heap_reserved_ = 0;  // bytes of blocks in budget_.heap (a block freed must subtract its `bytes`)
  int device_type_ = -1;  // memory type chosen for MemoryUse::device
};

// Bump allocator over one Buffer for the activations of a model call: alloc() during planning/recording,
// reset() before the next call. Views never straddle a binding limit.
class Arena {
 public:
  Arena(Allocator& alloc, VkDeviceSize capacity, const std::string& what = "activation arena");
  BufferView alloc(VkDeviceSize bytes);
  void reset() { used_ = 0; }
  VkDeviceSize used() const { return used_; }
  VkDeviceSize peak() const { return peak_; }
  VkDeviceSize capacity() const { return buffer_.size(); }

 private:
  Buffer buffer_;
  std::string what_;
  VkDeviceSize alignment_;
  VkDeviceSize used_ = 0, peak_ = 0;
};

std::string format_bytes(uint64_t bytes);

}  // namespace dvs::vk
