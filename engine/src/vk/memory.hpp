// Device memory: large VkDeviceMemory blocks (each ≤ maxMemoryAllocationSize, with one VkBuffer covering
// it) suballocated first-fit into Buffers; a block entirely free again goes back to the driver (one spare
// per use kept, see Allocator::release). A Buffer may be larger than one descriptor binds
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
  // Streamed weights (models/block_stream.hpp): both are shared by the compute queue and the transfer queue
  // (VK_SHARING_MODE_CONCURRENT where they are different families, so no ownership transfers are needed).
  device_shared,  // device-local, as `device`: the block slots the uploads fill
  pinned,         // host-visible host memory the transfer queue reads directly: the weights' host copy. Host
                  // memory, not device memory: outside the device budget and outside bytes_in_use (host_* stats)
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
  // No buffer lives in it: one free range, the whole block (ranges are coalesced, so it starts at 0).
  bool entirely_free() const { return free_ranges.size() == 1 && free_ranges.begin()->second == size; }
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

// Every use but MemoryUse::pinned, which the host_* figures count.
struct MemoryStats {
  uint64_t bytes_in_use = 0;
  uint64_t peak_bytes_in_use = 0;
  uint64_t bytes_reserved = 0;  // in VkDeviceMemory blocks
  uint64_t peak_bytes_reserved = 0;  // high-water mark of bytes_reserved (since reset_peak)
  uint32_t blocks = 0;
  uint64_t host_bytes_in_use = 0, host_bytes_reserved = 0;  // MemoryUse::pinned
};

class Allocator {
 public:
  explicit Allocator(Context& ctx);
  ~Allocator();

  // `what` names the request in error messages ("transformer weights", "attention scores", ...).
  Buffer allocate(VkDeviceSize bytes, MemoryUse use = MemoryUse::device, const std::string& what = "buffer");

  const MemoryStats& stats() const { return stats_; }
  // Restarts both peaks from what is held now, so the next peaks measure one call (benchmarks, dvs run).
  void reset_peak();
  VkDeviceSize alignment() const { return alignment_; }
  // The standard block: 256 MiB, or less where the allocation limit in force (DVS_LIMITS included) is lower.
  VkDeviceSize block_size() const;
  bool device_memory_is_mapped() const;  // unified memory: uploads are plain memcpy
  VkDeviceSize max_binding() const;      // maxStorageBufferRange
  VkDeviceSize max_allocation() const;   // maxMemoryAllocationSize in force (DVS_LIMITS included)

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
  // `injected_failure`: the driver's answer is VK_ERROR_OUT_OF_DEVICE_MEMORY (DVS_FAULTS=alloc=N).
  MemoryBlock* new_block(VkDeviceSize size, MemoryUse use, const std::string& what, bool injected_failure = false);
  void return_free_blocks(MemoryUse use);  // see memory.cpp for the policy
  bool release_spare_blocks();             // every entirely free device block, spares included; true if any
  void free_block(size_t index);
  uint32_t memory_type_for(MemoryUse use, uint32_t type_bits) const;
  void check_budget(VkDeviceSize size, uint32_t heap, const std::string& what) const;  // throws when over

  Context& ctx_;
  VkDeviceSize alignment_ = 256;
  std::vector<std::unique_ptr<MemoryBlock>> blocks_;
  MemoryStats stats_;
  DeviceMemoryBudget budget_;
  std::optional<uint64_t> limit_;
  uint64_t heap_reserved_ = 0;  // bytes of blocks in budget_.heap (a block freed must subtract its `bytes`)
  int device_type_ = -1;  // memory type chosen for MemoryUse::device
};

// The blocks of an arena, in bytes (each at most one allocation). A model's counting pass
// (models/activation_plan.hpp) gives the blocks its tensors fill, so the arena reserves no more than they use.
struct ArenaLayout {
  std::vector<VkDeviceSize> blocks;
  VkDeviceSize largest = 0;  // the largest tensor placed, aligned: it must fit one block (one allocation)
  VkDeviceSize bytes() const;
  // Whether an arena of these blocks can take what `other` was counted for: as many blocks, each as large.
  // (Placing in order, each tensor then lands no later than the counting put it.)
  bool holds(const ArenaLayout& other) const;
};

// How an arena places its tensors, shared by Arena and the counting pass so that the bytes a plan counts are
// the bytes the arena reserves: tensors bump-allocated in order within a block; one that does not fit the
// rest of a block starts the next. Block k holds `caps[k]` bytes, blocks past `caps` hold `then` (counting:
// no blocks yet, then the allocation limit; an arena: its blocks, then none). Each tensor is aligned (a
// sub-view start must be a binding offset).
class ArenaPacking {
 public:
  ArenaPacking(VkDeviceSize alignment, std::vector<VkDeviceSize> caps, VkDeviceSize then)
      : alignment_(alignment), caps_(std::move(caps)), then_(then) {}
  // The block an arena uses under an allocation limit: the limit aligned down (one block is one allocation).
  static VkDeviceSize block_limit(VkDeviceSize alloc_limit, VkDeviceSize alignment) {
    return alloc_limit / alignment * alignment;
  }
  VkDeviceSize aligned(VkDeviceSize bytes) const;  // bytes a tensor takes (≥ 4, rounded up to the alignment)
  VkDeviceSize capacity(size_t block) const { return block < caps_.size() ? caps_[block] : then_; }
  struct Place {
    size_t block;
    VkDeviceSize offset;
    bool fits;  // within its block's capacity
  };
  Place place(VkDeviceSize bytes);
  const ArenaLayout& filled() const { return filled_; }  // bytes each block holds so far
  void rewind() { *this = ArenaPacking(alignment_, std::move(caps_), then_); }

 private:
  VkDeviceSize alignment_;
  std::vector<VkDeviceSize> caps_;
  VkDeviceSize then_;
  ArenaLayout filled_;
};

// Bump allocator for the activations of a model call: alloc() during planning/recording, reset() before the
// next call. Its memory is one Buffer per block of its layout, each at most one allocation
// (maxMemoryAllocationSize); a call whose activations fit one allocation has one block. Views never straddle
// blocks.
class Arena {
 public:
  // The blocks a counting pass gave (models::ActivationPlan::layout()).
  Arena(Allocator& alloc, const ArenaLayout& layout, const std::string& what = "activation arena");
  // `capacity` bytes: one block where one allocation holds them, else blocks of the limit in force.
  Arena(Allocator& alloc, VkDeviceSize capacity, const std::string& what = "activation arena");
  BufferView alloc(VkDeviceSize bytes);
  void reset() { packing_.rewind(); }  // back to block 0; keeps the blocks
  VkDeviceSize used() const { return packing_.filled().bytes(); }
  VkDeviceSize peak() const { return peak_; }
  VkDeviceSize capacity() const { return layout_.bytes(); }
  const ArenaLayout& layout() const { return layout_; }
  size_t blocks() const { return blocks_.size(); }
  const Buffer& block(size_t i) const { return blocks_.at(i); }

 private:
  std::vector<Buffer> blocks_;
  ArenaLayout layout_;
  std::string what_;
  VkDeviceSize limit_;
  ArenaPacking packing_;
  VkDeviceSize peak_ = 0;
};

std::string format_bytes(uint64_t bytes);

}  // namespace dvs::vk
