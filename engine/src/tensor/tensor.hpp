// Tensor: a shape and dtype over a range of device memory. Owning tensors keep their Buffer alive through
// a shared_ptr (copies share storage); views over an Arena do not own. Data layout is always contiguous
// row-major; ops take explicit strides where they need other layouts.
#pragma once
#include <memory>
#include <string>

#include "io/host_tensor.hpp"
#include "vk/memory.hpp"

namespace dvs::vk {
class Context;
}

namespace dvs {

class Tensor {
 public:
  Tensor() = default;
  static Tensor empty(vk::Context& ctx, Shape shape, DType dtype, const std::string& what = "tensor");
  static Tensor zeros(vk::Context& ctx, Shape shape, DType dtype, const std::string& what = "tensor");
  static Tensor on(const vk::BufferView& view, Shape shape, DType dtype);  // non-owning
  static Tensor upload(vk::Context& ctx, const HostTensor& host, const std::string& what = "tensor");

  HostTensor download(vk::Context& ctx) const;
  void write(vk::Context& ctx, const HostTensor& host) const;  // same shape and dtype required

  const Shape& shape() const { return shape_; }
  DType dtype() const { return dtype_; }
  size_t rank() const { return shape_.size(); }
  int64_t dim(int i) const;  // negative counts from the end
  int64_t numel() const { return shape_numel(shape_); }
  size_t bytes() const { return size_t(numel()) * dtype_size(dtype_); }
  const vk::BufferView& buffer() const { return view_; }
  bool defined() const { return view_.valid(); }

  Tensor reshape(Shape shape) const;                      // same element count
  Tensor rows(int64_t first, int64_t count) const;        // slice of the outermost dimension
  std::string describe() const;                           // "f32[1x3x8x8]"

 private:
  Shape shape_;
  DType dtype_ = DType::f32;
  vk::BufferView view_;
  std::shared_ptr<vk::Buffer> storage_;
};

}  // namespace dvs
