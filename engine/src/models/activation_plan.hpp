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
  // Counting pass; alloc_limit: maxMemoryAllocationSize in force (no limit: one block).
  explicit ActivationPlan(VkDeviceSize alignment, VkDeviceSize alloc_limit = std::numeric_limits<VkDeviceSize>::max(),
                          std::string what = "activation arena")
      : limit_(vk::ArenaPacking::block_limit(alloc_limit, alignment)),
        what_(std::move(what)),
        packing_(alignment, {}, limit_) {}
  // Allocating pass.
  explicit ActivationPlan(vk::Arena& arena) : arena_(&arena), packing_(1, {}, 0) {}

  Tensor make(Shape shape, DType dtype = DType::f32) {
    const VkDeviceSize bytes = VkDeviceSize(shape_numel(shape)) * dtype_size(dtype);
    if (!arena_) {
      if (packing_.aligned(bytes) > limit_)
        throw Error("The " + what_ + " needs a tensor of " + shape_str(shape) + " " + dtype_name(dtype) + " (" +
                    vk::format_bytes(bytes) + "), more than one allocation on this device (maxMemoryAllocationSize " +
                    vk::format_bytes(limit_) + "). Use a smaller --height/--width or fewer --frames, or a device "
                    "that allocates more at once (dvs plan --device shows each stage's largest tensor).");
      packing_.place(bytes);
      return {};
    }
    return Tensor::on(arena_->alloc(bytes), std::move(shape), dtype);
  }
  bool counting() const { return arena_ == nullptr; }
  // The arena's blocks for what was counted: one block when it fits one allocation, else each block as full
  // as the tensors that went into it (vk::Arena places them the same way).
  const vk::ArenaLayout& layout() const { return packing_.filled(); }
  VkDeviceSize bytes() const { return layout().bytes(); }

 private:
  vk::Arena* arena_ = nullptr;
  VkDeviceSize limit_ = 0;
  std::string what_;
  vk::ArenaPacking packing_;
};

// A flat f32 view of `count` elements of `t` starting at element `first` (for strided linear layouts).
inline Tensor element_range(const Tensor& t, int64_t first, int64_t count) {
  const size_t es = dtype_size(t.dtype());
  return Tensor::on(t.buffer().sub(VkDeviceSize(first) * es, VkDeviceSize(count) * es), {count}, t.dtype());
}

// Keeps an arena big enough for the largest call seen so far (re-created when a call needs more).
inline vk::Arena& arena_for(vk::Context& ctx, std::unique_ptr<vk::Arena>& arena, const vk::ArenaLayout& layout,
                            const char* what) {
  if (!arena || !arena->layout().holds(layout)) {
    arena.reset();
    arena = std::make_unique<vk::Arena>(ctx.allocator(), layout, what);
  }
  arena->reset();
  return *arena;
}

}  // namespace dvs::models
