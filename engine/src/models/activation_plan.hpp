// Sizing the activation arena of a model call from its shapes: the model lists its activation tensors once
// through an ActivationPlan; a plan without an arena only counts the bytes, packing the tensors over blocks as
// the arena will (vk::ArenaPacking: alignment, blocks of at most one allocation), a plan over an arena hands
// out the tensors. Running the same listing twice keeps size and use in step: bytes() is what the arena reserves.
#pragma once
#include <algorithm>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "dvs/error.hpp"
#include "io/host_tensor.hpp"
#include "tensor/tensor.hpp"
#include "vk/context.hpp"
#include "vk/memory.hpp"

namespace dvs::models {

class ActivationPlan {
 public:
  // Counting pass; alloc_limit: maxMemoryAllocationSize in force (no limit: the bytes of one block).
  explicit ActivationPlan(VkDeviceSize alignment, VkDeviceSize alloc_limit = std::numeric_limits<VkDeviceSize>::max(),
                          std::string what = "activation arena")
      : alignment_(alignment),
        limit_(vk::ArenaPacking::block_limit(alloc_limit, alignment)),
        what_(std::move(what)) {}
  // Allocating pass.
  explicit ActivationPlan(vk::Arena& arena) : arena_(&arena) {}

  Tensor make(Shape shape, DType dtype = DType::f32) {
    const VkDeviceSize bytes = VkDeviceSize(shape_numel(shape)) * dtype_size(dtype);
    if (!arena_) {
      const VkDeviceSize need = vk::ArenaPacking(alignment_, limit_).aligned(bytes);
      if (need > limit_)
        throw Error("The " + what_ + " needs a tensor of " + shape_str(shape) + " " + dtype_name(dtype) + " (" +
                    vk::format_bytes(bytes) + "), more than one allocation on this device (maxMemoryAllocationSize " +
                    vk::format_bytes(limit_) + "). Use a smaller --height/--width or fewer --frames, or a device "
                    "that allocates more at once (dvs plan --device shows each stage's largest tensor).");
      sizes_.push_back(need);
      total_ += need;
      return {};
    }
    return Tensor::on(arena_->alloc(bytes), std::move(shape), dtype);
  }
  bool counting() const { return arena_ == nullptr; }
  // The arena's capacity for what was counted: one block when it fits one allocation, else full blocks of the
  // limit and a last one as large as its contents (vk::Arena cuts the same blocks from this figure).
  VkDeviceSize bytes() const {
    vk::ArenaPacking packing(alignment_, std::min(limit_, total_));
    for (VkDeviceSize s : sizes_) packing.place(s);
    return packing.reserved();
  }

 private:
  vk::Arena* arena_ = nullptr;
  VkDeviceSize alignment_ = 256, limit_ = 0;
  std::string what_;
  std::vector<VkDeviceSize> sizes_;  // aligned, in order
  VkDeviceSize total_ = 0;
};

// A flat f32 view of `count` elements of `t` starting at element `first` (for strided linear layouts).
inline Tensor element_range(const Tensor& t, int64_t first, int64_t count) {
  const size_t es = dtype_size(t.dtype());
  return Tensor::on(t.buffer().sub(VkDeviceSize(first) * es, VkDeviceSize(count) * es), {count}, t.dtype());
}

// Keeps an arena big enough for the largest call seen so far (re-created when a call needs more, or when the
// allocation limit changed: `bytes`, counted under today's limit, then assumes other blocks).
inline vk::Arena& arena_for(vk::Context& ctx, std::unique_ptr<vk::Arena>& arena, VkDeviceSize bytes,
                            const char* what) {
  const VkDeviceSize limit = vk::ArenaPacking::block_limit(ctx.allocator().max_allocation(), ctx.allocator().alignment());
  if (!arena || arena->capacity() < bytes || arena->alloc_limit() != limit) {
    arena.reset();
    arena = std::make_unique<vk::Arena>(ctx.allocator(), std::max<VkDeviceSize>(bytes, 256), what);
  }
  arena->reset();
  return *arena;
}

}  // namespace dvs::models
