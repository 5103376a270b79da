// Sizing the activation arena of a model call from its shapes: the model lists its activation tensors once
// through an ActivationPlan; a plan without an arena only adds up the bytes (with the arena's alignment), a
// plan over an arena hands out the tensors. Running the same listing twice keeps size and use in step.
#pragma once
#include <algorithm>
#include <cstdint>
#include <memory>

#include "tensor/tensor.hpp"
#include "vk/context.hpp"
#include "vk/memory.hpp"

namespace dvs::models {

class ActivationPlan {
 public:
  // Counting pass.
  explicit ActivationPlan(VkDeviceSize alignment) : alignment_(alignment) {}
  // Allocating pass.
  explicit ActivationPlan(vk::Arena& arena) : arena_(&arena) {}

  Tensor make(Shape shape, DType dtype = DType::f32) {
    const VkDeviceSize bytes = VkDeviceSize(shape_numel(shape)) * dtype_size(dtype);
    if (!arena_) {
      const VkDeviceSize need = std::max<VkDeviceSize>(bytes, 4);
      bytes_ += (need + alignment_ - 1) / alignment_ * alignment_;
      return {};
    }
    return Tensor::on(arena_->alloc(bytes), std::move(shape), dtype);
  }
  bool counting() const { return arena_ == nullptr; }
  VkDeviceSize bytes() const { return bytes_; }

 private:
  vk::Arena* arena_ = nullptr;
  VkDeviceSize alignment_ = 256;
  VkDeviceSize bytes_ = 0;
};

// A flat f32 view of `count` elements of `t` starting at element `first` (for strided linear layouts).
inline Tensor element_range(const Tensor& t, int64_t first, int64_t count) {
  const size_t es = dtype_size(t.dtype());
  return Tensor::on(t.buffer().sub(VkDeviceSize(first) * es, VkDeviceSize(count) * es), {count}, t.dtype());
}

// Keeps an arena big enough for the largest call seen so far (re-created when a call needs more).
inline vk::Arena& arena_for(vk::Context& ctx, std::unique_ptr<vk::Arena>& arena, VkDeviceSize bytes,
                            const char* what) {
  if (!arena || arena->capacity() < bytes) {
    arena.reset();
    arena = std::make_unique<vk::Arena>(ctx.allocator(), std::max<VkDeviceSize>(bytes, 256), what);
  }
  arena->reset();
  return *arena;
}

}  // namespace dvs::models
