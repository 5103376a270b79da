#include "vk/memory.hpp"

#include <algorithm>
#include <sstream>

#include "io/injected_faults.hpp"
#include "vk/check.hpp"
#include "vk/context.hpp"

namespace dvs::vk {

std::string format_bytes(uint64_t b) {
  std::ostringstream o;
  o.setf(std::ios::fixed);
  o.precision(1);
  if (b >= (1ull << 30)) o << double(b) / double(1ull << 30) << " GiB";
  else if (b >= (1ull << 20)) o << double(b) / double(1ull << 20) << " MiB";
  else if (b >= 1024) o << double(b) / 1024.0 << " KiB";
  else o << b << " B";
  return o.str();
}

static VkDeviceSize align_up(VkDeviceSize v, VkDeviceSize a) { return (v + a - 1) / a * a; }

BufferView BufferView::sub(VkDeviceSize off, VkDeviceSize bytes) const {
  if (off > size || bytes > size - off)
    throw Error("internal: buffer sub-range [" + std::to_string(off) + ", +" + std::to_string(bytes) +
                ") outside a view of " + std::to_string(size) + " bytes");
  BufferView v = *this;
  v.offset += off;
  v.size = bytes;
  if (mapped) v.mapped = mapped + off;
  return v;
}

// ---- Buffer ------------------------------------------------------------------------------------------

Buffer::~Buffer() {
  if (owner_) owner_->release(*this);
}

Buffer::Buffer(Buffer&& o) noexcept
    : owner_(o.owner_), block_(o.block_), reserved_(o.reserved_), view_(o.view_) {
  o.owner_ = nullptr;
  o.block_ = nullptr;
  o.view_ = {};
}

Buffer& Buffer::operator=(Buffer&& o) noexcept {
  if (this != &o) {
    if (owner_) owner_->release(*this);
    owner_ = o.owner_;
    block_ = o.block_;
    reserved_ = o.reserved_;
    view_ = o.view_;
    o.owner_ = nullptr;
    o.block_ = nullptr;
    o.view_ = {};
  }
  return *this;
}

// ---- Allocator ---------------------------------------------------------------------------------------

Allocator::Allocator(Context& ctx) : ctx_(ctx) {
  const DeviceCaps& c = ctx.caps();
  VkPhysicalDeviceProperties p{};
  vkGetPhysicalDeviceProperties(ctx.physical_device(), &p);
  alignment_ = std::max<VkDeviceSize>({64, c.min_storage_buffer_offset_alignment, p.limits.minTexelBufferOffsetAlignment,
                                       p.limits.nonCoherentAtomSize});
  // Host RAM available now on a CPU device, the heap budget or size on a GPU (memory_budget.hpp).
  budget_ = query_memory_budget(ctx.physical_device(), c.type, c.memory_budget_ext);
}

void Allocator::limit_device_memory(uint64_t bytes) { limit_ = limit_ ? std::min(*limit_, bytes) : bytes; }

uint64_t Allocator::device_memory_capacity() const {
  uint64_t cap = budget_.bytes;
  if (limit_) cap = std::min(cap, *limit_);
  if (ctx_.caps().forced_limits.memory) cap = std::min(cap, ctx_.caps().memory_budget.bytes);  // DVS_LIMITS memory=
  return cap;
}

void Allocator::check_budget(VkDeviceSize size, uint32_t heap, const std::string& what) const {
  if (heap != budget_.heap) return;  // staging in a host heap of a discrete GPU: not device memory
  uint64_t after = heap_reserved_ + size;
  uint64_t cap = device_memory_capacity();
  std::string source = budget_.describe();
  if (budget_.source == MemoryBudgetSource::heap_budget) {
    // The budget moves with other processes: read it now. Usage counts this process' whole use of the heap.
    if (auto hb = query_heap_budget(ctx_.physical_device(), true, budget_.heap)) {
      after = std::max(after, hb->usage + size);
      if ((!limit_ && !ctx_.caps().forced_limits.memory) || hb->budget < cap) {
        cap = hb->budget;
        source = format_bytes(hb->budget) + " (VK_EXT_memory_budget heapBudget of heap " + std::to_string(heap) + ", now)";
      }
    }
  }
  if (limit_ && cap == *limit_) source = format_bytes(cap) + " (limit set by Allocator::limit_device_memory)";
  if (ctx_.caps().forced_limits.memory && cap == ctx_.caps().memory_budget.bytes)
    source = format_bytes(cap) + " (DVS_LIMITS memory=)";
  if (after > cap)
    throw DeviceOutOfMemory("Out of device memory: " + what + " needs a new block of " + format_bytes(size) +
                                ", which would bring dvs's device memory to " + format_bytes(after) + ", over the " +
                                source + " it may use",
                            kOutOfMemoryHint);
}

Allocator::~Allocator() {
  VkDevice dev = ctx_.device();
  for (auto& b : blocks_) {
    if (b->buffer) vkDestroyBuffer(dev, b->buffer, nullptr);
    if (b->memory) vkFreeMemory(dev, b->memory, nullptr);
  }
}

VkDeviceSize Allocator::max_binding() const { return ctx_.caps().max_storage_buffer_range; }

VkDeviceSize Allocator::max_allocation() const { return ctx_.caps().max_memory_allocation_size; }

// Big enough that weights and arenas rarely need their own block, small enough to fit any limit. Read at each
// allocation: ScopedLimits / override_limits may lower the limit while the allocator lives.
VkDeviceSize Allocator::block_size() const { return std::min<VkDeviceSize>(256ull << 20, max_allocation()); }

void Allocator::reset_peak() {
  stats_.peak_bytes_in_use = stats_.bytes_in_use;
  stats_.peak_bytes_reserved = stats_.bytes_reserved;
}

bool Allocator::device_memory_is_mapped() const {
  VkPhysicalDeviceMemoryProperties mp{};
  vkGetPhysicalDeviceMemoryProperties(ctx_.physical_device(), &mp);
  uint32_t t = memory_type_for(MemoryUse::device, ~0u);
  return mp.memoryTypes[t].propertyFlags & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT;
}

uint32_t Allocator::memory_type_for(MemoryUse use, uint32_t type_bits) const {
  VkPhysicalDeviceMemoryProperties mp{};
  vkGetPhysicalDeviceMemoryProperties(ctx_.physical_device(), &mp);
  const VkMemoryPropertyFlags host = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  auto find = [&](VkMemoryPropertyFlags want, VkMemoryPropertyFlags avoid) -> int {
    for (uint32_t t = 0; t < mp.memoryTypeCount; ++t) {
      VkMemoryPropertyFlags f = mp.memoryTypes[t].propertyFlags;
      if ((type_bits & (1u << t)) && (f & want) == want && !(f & avoid)) return int(t);
    }
    return -1;
  };
  int t = -1;
  if (use == MemoryUse::device || use == MemoryUse::device_shared) {
    // Unified memory: the largest device-local heap is also host-visible; map it and skip staging.
    uint32_t big_heap = device_heap_index(mp);
    for (uint32_t i = 0; i < mp.memoryTypeCount && t < 0; ++i) {
      VkMemoryPropertyFlags f = mp.memoryTypes[i].propertyFlags;
      if ((type_bits & (1u << i)) && mp.memoryTypes[i].heapIndex == big_heap &&
          (f & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT) && (f & host) == host)
        t = int(i);
    }
    if (t < 0) t = find(VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT, 0);
    if (t < 0) t = find(0, 0);
  } else if (use == MemoryUse::upload || use == MemoryUse::pinned) {
    t = find(host, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    if (t < 0) t = find(host, 0);
  } else {
    t = find(host | VK_MEMORY_PROPERTY_HOST_CACHED_BIT, 0);
    if (t < 0) t = find(host, 0);
  }
  if (t < 0) throw Error("The Vulkan device offers no memory type usable for dvs buffers.");
  return uint32_t(t);
}

MemoryBlock* Allocator::new_block(VkDeviceSize size, MemoryUse use, const std::string& what, bool injected_failure) {
  VkDevice dev = ctx_.device();
  auto block = std::make_unique<MemoryBlock>();
  block->size = size;
  block->use = use;
  VkBufferCreateInfo bci{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bci.size = size;
  bci.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT |
              VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT | VK_BUFFER_USAGE_STORAGE_TEXEL_BUFFER_BIT |
              VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  bci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  const uint32_t families[2] = {ctx_.queue_family(), ctx_.transfer_queue_family()};
  if ((use == MemoryUse::device_shared || use == MemoryUse::pinned) && ctx_.has_transfer_queue()) {
    bci.sharingMode = VK_SHARING_MODE_CONCURRENT;  // written by the transfer queue, read by the compute queue
    bci.queueFamilyIndexCount = 2;
    bci.pQueueFamilyIndices = families;
  }
  VK_CHECK(vkCreateBuffer(dev, &bci, nullptr, &block->buffer));
  VkMemoryRequirements req{};
  vkGetBufferMemoryRequirements(dev, block->buffer, &req);
  VkMemoryAllocateInfo mai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  mai.allocationSize = req.size;
  mai.memoryTypeIndex = memory_type_for(use, req.memoryTypeBits);
  VkPhysicalDeviceMemoryProperties mp{};
  vkGetPhysicalDeviceMemoryProperties(ctx_.physical_device(), &mp);
  const uint32_t heap = mp.memoryTypes[mai.memoryTypeIndex].heapIndex;
  const bool host_memory = use == MemoryUse::pinned;  // not device memory, even where it shares the heap
  try {
    if (!host_memory) check_budget(req.size, heap, what);
  } catch (...) {
    vkDestroyBuffer(dev, block->buffer, nullptr);
    throw;
  }
  VkResult r = injected_failure ? VK_ERROR_OUT_OF_DEVICE_MEMORY : vkAllocateMemory(dev, &mai, nullptr, &block->memory);
  if (r != VK_SUCCESS) {
    vkDestroyBuffer(dev, block->buffer, nullptr);
    if (r == VK_ERROR_OUT_OF_DEVICE_MEMORY || r == VK_ERROR_OUT_OF_HOST_MEMORY)
      throw DeviceOutOfMemory("Out of device memory: allocating " + format_bytes(req.size) + " for " + what +
                                  " failed (" + result_name(r) + "; " + format_bytes(stats_.bytes_reserved) +
                                  " already held by dvs)",
                              kOutOfMemoryHint);
    VK_CHECK(r);
  }
  VK_CHECK(vkBindBufferMemory(dev, block->buffer, block->memory, 0));
  block->heap = heap;
  block->bytes = req.size;
  if (heap == budget_.heap && !host_memory) heap_reserved_ += req.size;
  if (mp.memoryTypes[mai.memoryTypeIndex].propertyFlags & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) {
    void* p = nullptr;
    VK_CHECK(vkMapMemory(dev, block->memory, 0, VK_WHOLE_SIZE, 0, &p));
    block->mapped = static_cast<uint8_t*>(p);
  }
  block->free_ranges[0] = size;
  if (host_memory) {
    stats_.host_bytes_reserved += size;
  } else {
    stats_.bytes_reserved += size;
    stats_.peak_bytes_reserved = std::max(stats_.peak_bytes_reserved, stats_.bytes_reserved);
  }
  stats_.blocks++;
  blocks_.push_back(std::move(block));
  return blocks_.back().get();
}

Buffer Allocator::allocate(VkDeviceSize bytes, MemoryUse use, const std::string& what) {
  const DeviceCaps& c = ctx_.caps();
  // An Arena over several blocks names its first one "<what> (block 1 of N)": that arena took the split path.
  if (what.size() > 12 && what.find(" (block 1 of ") != std::string::npos) ctx_.note_split("arena blocks");
  if (bytes == 0) bytes = 4;  // zero-size tensors still get a valid binding
  if (bytes > c.max_memory_allocation_size)
    throw Error("Buffer for " + what + " needs " + format_bytes(bytes) + ", more than this device can allocate at "
                "once (maxMemoryAllocationSize " + format_bytes(c.max_memory_allocation_size) + ").");
  VkDeviceSize need = align_up(bytes, alignment_);

  MemoryBlock* block = nullptr;
  VkDeviceSize offset = 0;
  for (auto& b : blocks_) {
    if (b->use != use) continue;
    for (auto& [off, size] : b->free_ranges)
      if (size >= need) {  // offsets are always multiples of the alignment
        block = b.get();
        offset = off;
        break;
      }
    if (block) break;
  }
  // DVS_FAULTS=alloc=N counts every allocation, also those a free range would hold: the Nth asks the driver for
  // a block of its own and gets VK_ERROR_OUT_OF_DEVICE_MEMORY, through the real error path (io/injected_faults.hpp).
  const bool injected = faults::fail_now(faults::Kind::alloc, what);
  if (!block || injected) {
    const VkDeviceSize size = injected ? need : std::max(need, block_size());
    try {
      block = new_block(size, use, what, injected);
    } catch (const DeviceOutOfMemory&) {
      // The spare blocks return_free_blocks keeps (one standard block per use) are memory nothing holds: give
      // them back and ask once more before refusing.
      if (injected || !release_spare_blocks()) throw;
      block = new_block(size, use, what, false);
    }
    offset = 0;
  }
  VkDeviceSize range = block->free_ranges[offset];
  block->free_ranges.erase(offset);
  if (range > need) block->free_ranges[offset + need] = range - need;

  Buffer buf;
  buf.owner_ = this;
  buf.block_ = block;
  buf.reserved_ = need;
  buf.view_.buffer = block->buffer;
  buf.view_.offset = offset;
  buf.view_.size = bytes;
  buf.view_.mapped = block->mapped ? block->mapped + offset : nullptr;
  if (use == MemoryUse::pinned) {
    stats_.host_bytes_in_use += need;
  } else {
    stats_.bytes_in_use += need;
    stats_.peak_bytes_in_use = std::max(stats_.peak_bytes_in_use, stats_.bytes_in_use);
  }
  return buf;
}

void Allocator::release(Buffer& b) {
  MemoryBlock* block = b.block_;
  VkDeviceSize off = b.view_.offset, size = b.reserved_;
  auto& fr = block->free_ranges;
  auto next = fr.lower_bound(off);
  if (next != fr.end() && off + size == next->first) {  // merge with the following range
    size += next->second;
    next = fr.erase(next);
  }
  if (next != fr.begin()) {  // merge with the preceding range
    auto prev = std::prev(next);
    if (prev->first + prev->second == off) {
      prev->second += size;
      size = 0;
    }
  }
  if (size) fr[off] = size;
  (block->use == MemoryUse::pinned ? stats_.host_bytes_in_use : stats_.bytes_in_use) -= b.reserved_;
  b.owner_ = nullptr;
  b.block_ = nullptr;
  b.view_ = {};
  if (block->entirely_free()) return_free_blocks(block->use);
}

// Entirely free blocks of `use` go back to the driver, except one of the standard size. Why one spare: small
// buffers (recorder scratch, per-step tensors, staging) come and go every op or step; if the last of them
// emptied a standard block that was then freed, the next would allocate (and map) a fresh one each time. One
// spare per use bounds what stays held unused to one standard block (≤ 256 MiB); blocks of any other size
// (dedicated to weights, arenas, big tensors: a phase's memory) and spares cut for an older limit always go.
void Allocator::return_free_blocks(MemoryUse use) {
  const VkDeviceSize standard = block_size();
  bool kept = false;
  for (size_t i = blocks_.size(); i-- > 0;) {
    MemoryBlock& b = *blocks_[i];
    if (b.use != use || !b.entirely_free()) continue;
    if (!kept && b.size == standard) {
      kept = true;
      continue;
    }
    free_block(i);
  }
}

bool Allocator::release_spare_blocks() {
  bool released = false;
  for (size_t i = blocks_.size(); i-- > 0;) {
    const MemoryBlock& b = *blocks_[i];
    if (b.use == MemoryUse::pinned || !b.entirely_free()) continue;
    free_block(i);
    released = true;
  }
  return released;
}

void Allocator::free_block(size_t index) {
  VkDevice dev = ctx_.device();
  MemoryBlock& b = *blocks_[index];
  vkDestroyBuffer(dev, b.buffer, nullptr);
  vkFreeMemory(dev, b.memory, nullptr);  // unmaps too
  if (b.use == MemoryUse::pinned) {
    stats_.host_bytes_reserved -= b.size;
  } else {
    if (b.heap == budget_.heap) heap_reserved_ -= b.bytes;
    stats_.bytes_reserved -= b.size;
  }
  stats_.blocks--;
  blocks_.erase(blocks_.begin() + std::ptrdiff_t(index));
}

// ---- Arena -------------------------------------------------------------------------------------------

VkDeviceSize ArenaLayout::bytes() const {
  VkDeviceSize n = 0;
  for (VkDeviceSize b : blocks) n += b;
  return n;
}

bool ArenaLayout::holds(const ArenaLayout& other) const {
  if (other.blocks.size() > blocks.size()) return false;
  for (size_t i = 0; i < other.blocks.size(); ++i)
    if (other.blocks[i] > blocks[i]) return false;
  return true;
}

VkDeviceSize ArenaPacking::aligned(VkDeviceSize bytes) const {
  return align_up(std::max<VkDeviceSize>(bytes, 4), alignment_);
}

ArenaPacking::Place ArenaPacking::place(VkDeviceSize bytes) {
  const VkDeviceSize need = aligned(bytes);
  if (filled_.blocks.empty()) filled_.blocks.push_back(0);
  size_t k = filled_.blocks.size() - 1;
  if (filled_.blocks[k] > 0 && filled_.blocks[k] + need > capacity(k)) {  // not the rest of this block: the next
    filled_.blocks.push_back(0);
    ++k;
  }
  Place p{k, filled_.blocks[k], filled_.blocks[k] + need <= capacity(k)};
  filled_.blocks[k] += need;
  filled_.largest = std::max(filled_.largest, need);
  return p;
}

// Blocks for `capacity` bytes: one where one allocation holds them, else as many of the limit as needed.
static ArenaLayout blocks_for(VkDeviceSize capacity, VkDeviceSize limit) {
  ArenaLayout l;
  for (VkDeviceSize left = std::max<VkDeviceSize>(capacity, 4); left > 0;) {
    l.blocks.push_back(std::min(limit, left));
    left -= l.blocks.back();
  }
  return l;
}

Arena::Arena(Allocator& alloc, VkDeviceSize capacity, const std::string& what)
    : Arena(alloc, blocks_for(align_up(capacity, alloc.alignment()),
                              ArenaPacking::block_limit(alloc.max_allocation(), alloc.alignment())), what) {}

Arena::Arena(Allocator& alloc, const ArenaLayout& layout, const std::string& what)
    : layout_(layout),
      what_(what),
      limit_(ArenaPacking::block_limit(alloc.max_allocation(), alloc.alignment())),
      packing_(alloc.alignment(), {}, 0) {
  if (limit_ == 0)
    throw Error("internal: maxMemoryAllocationSize " + format_bytes(alloc.max_allocation()) + " is below the " +
                format_bytes(alloc.alignment()) + " alignment of a buffer");
  if (layout_.blocks.empty()) layout_.blocks.push_back(4);
  const size_t count = layout_.blocks.size();
  blocks_.reserve(count);
  for (VkDeviceSize& b : layout_.blocks) {
    b = align_up(std::max<VkDeviceSize>(b, 4), alloc.alignment());
    std::string name = what_;
    if (count > 1) name += " (block " + std::to_string(blocks_.size() + 1) + " of " + std::to_string(count) + ")";
    blocks_.push_back(alloc.allocate(b, MemoryUse::device, name));
  }
  packing_ = ArenaPacking(alloc.alignment(), layout_.blocks, 0);
}

BufferView Arena::alloc(VkDeviceSize bytes) {
  const VkDeviceSize need = packing_.aligned(bytes);
  if (need > limit_)
    throw Error("A tensor of " + format_bytes(bytes) + " in the " + what_ + " is larger than one allocation on this "
                "device (maxMemoryAllocationSize " + format_bytes(limit_) + "). Use a smaller size or tiling.");
  const ArenaPacking saved = packing_;
  const ArenaPacking::Place p = packing_.place(bytes);
  if (!p.fits) {
    packing_ = saved;
    throw Error("The " + what_ + " of " + format_bytes(capacity()) + " is full: " + format_bytes(used()) + " used, " +
                format_bytes(bytes) + " more requested. Use a smaller size or tiling.");
  }
  peak_ = std::max(peak_, used());
  return blocks_[p.block].view().sub(p.offset, std::max<VkDeviceSize>(bytes, 4));
}

}  // namespace dvs::vk
