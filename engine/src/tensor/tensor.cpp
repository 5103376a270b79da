#include "tensor/tensor.hpp"

#include "dvs/error.hpp"
#include "vk/context.hpp"
#include "vk/transfer.hpp"

namespace dvs {

static void check_shape(const Shape& s) {
  for (int64_t d : s)
    if (d < 0) throw Error("internal: negative tensor dimension in " + shape_str(s));
}

Tensor Tensor::empty(vk::Context& ctx, Shape shape, DType dtype, const std::string& what) {
  check_shape(shape);
  Tensor t;
  t.shape_ = std::move(shape);
  t.dtype_ = dtype;
  t.storage_ = std::make_shared<vk::Buffer>(ctx.allocator().allocate(t.bytes(), vk::MemoryUse::device, what));
  t.view_ = t.storage_->view();
  return t;
}

Tensor Tensor::zeros(vk::Context& ctx, Shape shape, DType dtype, const std::string& what) {
  Tensor t = empty(ctx, std::move(shape), dtype, what);
  ctx.transfer().fill_zero(t.view_);
  return t;
}

Tensor Tensor::on(const vk::BufferView& view, Shape shape, DType dtype) {
  check_shape(shape);
  Tensor t;
  t.shape_ = std::move(shape);
  t.dtype_ = dtype;
  if (t.bytes() > view.size)
    throw Error("internal: tensor " + t.describe() + " does not fit a view of " + std::to_string(view.size) + " bytes");
  t.view_ = view.sub(0, std::max<VkDeviceSize>(t.bytes(), std::min<VkDeviceSize>(4, view.size)));
  return t;
}

Tensor Tensor::upload(vk::Context& ctx, const HostTensor& host, const std::string& what) {
  Tensor t = empty(ctx, host.shape, host.dtype, what);
  t.write(ctx, host);
  return t;
}

void Tensor::write(vk::Context& ctx, const HostTensor& host) const {
  if (host.shape != shape_ || host.dtype != dtype_)
    throw Error("internal: writing " + std::string(dtype_name(host.dtype)) + "[" + shape_str(host.shape) +
                "] into tensor " + describe());
  if (!host.data.empty()) ctx.transfer().upload(view_, host.data.data(), host.data.size());
}

HostTensor Tensor::download(vk::Context& ctx) const {
  HostTensor h(shape_, dtype_);
  if (!h.data.empty()) ctx.transfer().download(view_, h.data.data(), h.data.size());
  return h;
}

int64_t Tensor::dim(int i) const {
  int r = int(shape_.size());
  if (i < 0) i += r;
  if (i < 0 || i >= r) throw Error("internal: dimension " + std::to_string(i) + " of tensor " + describe());
  return shape_[size_t(i)];
}

Tensor Tensor::reshape(Shape shape) const {
  if (shape_numel(shape) != numel())
    throw Error("internal: cannot reshape " + describe() + " to [" + shape_str(shape) + "]");
  Tensor t = *this;
  t.shape_ = std::move(shape);
  return t;
}

Tensor Tensor::rows(int64_t first, int64_t count) const {
  if (shape_.empty() || first < 0 || count < 0 || first + count > shape_[0])
    throw Error("internal: rows [" + std::to_string(first) + ", +" + std::to_string(count) + ") of " + describe());
  size_t row_bytes = shape_[0] ? bytes() / size_t(shape_[0]) : 0;
  Tensor t = *this;
  t.shape_[0] = count;
  t.view_ = view_.sub(VkDeviceSize(first) * row_bytes, std::max<VkDeviceSize>(VkDeviceSize(count) * row_bytes, 4));
  return t;
}

std::string Tensor::describe() const { return std::string(dtype_name(dtype_)) + "[" + shape_str(shape_) + "]"; }

}  // namespace dvs
