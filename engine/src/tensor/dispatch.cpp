#include "tensor/dispatch.hpp"

#include "vk/context.hpp"

namespace dvs::ops {

Grid grid_1d(int64_t items, uint32_t local) {
  Grid g;
  int64_t groups = (items + local - 1) / local;
  if (groups <= 65535) {
    g.x = uint32_t(groups);
  } else {
    g.x = 65535;
    g.y = uint32_t((groups + 65534) / 65535);
    if (g.y > 65535) throw Error("internal: dispatch of " + std::to_string(items) + " items is too large");
  }
  return g;
}

void run_now(vk::Context& ctx, const std::function<void(vk::Recorder&)>& record) {
  vk::Recorder rec(ctx);
  rec.begin();
  record(rec);
  rec.submit();
}

void expect_shape(const char* op, const char* arg, const Tensor& t, const Shape& shape) {
  if (t.shape() != shape)
    throw Error(std::string("internal: ") + op + ": " + arg + " is " + t.describe() + ", expected [" + shape_str(shape) + "]");
}

void expect_dtype(const char* op, const char* arg, const Tensor& t, DType dtype) {
  if (t.dtype() != dtype)
    throw Error(std::string("internal: ") + op + ": " + arg + " is " + t.describe() + ", expected " + dtype_name(dtype));
}

}  // namespace dvs::ops
