#include "tensor/ops_check.hpp"

#include <algorithm>
#include <cstring>

#include "dvs/error.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops {
namespace {

constexpr uint32_t kNone = 0xffffffffu;
constexpr uint32_t kRun = 16, kLocal = 64;  // about kRun vec4s per invocation; workgroup size (nonfinite.comp)

std::string format_shape(const Shape& s) {
  std::string r = "[";
  for (size_t i = 0; i < s.size(); ++i) {
    if (i) r += ",";
    r += std::to_string(s[i]);
  }
  return r + "]";
}

}  // namespace

std::string format_index(const Shape& shape, int64_t flat) {
  std::vector<int64_t> idx(shape.size(), 0);
  for (size_t i = shape.size(); i-- > 0;) {
    const int64_t d = std::max<int64_t>(shape[i], 1);
    idx[i] = flat % d;
    flat /= d;
  }
  return format_shape(idx);
}

std::string NonFiniteHit::message() const {
  return what + " " + format_shape(shape) + ": " + std::to_string(count) + " non-finite value" + (count == 1 ? "" : "s") +
         " (NaN/Inf), the first at " + format_index(shape, first) + " (flat index " + std::to_string(first) + ")";
}

NonFiniteCheck::NonFiniteCheck(vk::Context& ctx, int slots) : ctx_(ctx), slots_(slots) {
  result_ = ctx.allocator().allocate(VkDeviceSize(slots) * 2 * sizeof(uint32_t), vk::MemoryUse::readback,
                                     "non-finite check results");
  if (!result_.mapped()) throw Error("internal: NonFiniteCheck: the result buffer is not host-visible");
  clear();
}

void NonFiniteCheck::clear() {
  auto* r = reinterpret_cast<uint32_t*>(result_.mapped());
  for (int i = 0; i < slots_; ++i) r[2 * i] = 0, r[2 * i + 1] = kNone;
  used_.clear();
}

void NonFiniteCheck::record(vk::Recorder& rec, const Tensor& t, const std::string& what, VkDeviceSize range_bytes) {
  expect_dtype("NonFiniteCheck", what.c_str(), t, DType::f32);
  if (int(used_.size()) >= slots_) throw Error("internal: NonFiniteCheck: more than " + std::to_string(slots_) + " scans");
  if (t.numel() >= int64_t(kNone)) throw Error("internal: NonFiniteCheck: " + t.describe() + " is too large");
  const uint32_t slot = uint32_t(used_.size());
  used_.push_back({what, t.shape()});
  // Ranges within one binding (a decoded video at the real size is ~200 MB), whole vec4s, aligned starts;
  // range_bytes (tests) caps them lower.
  const int64_t n = t.numel();
  int64_t per = rows_per_chunk(ctx_.caps(), "NonFiniteCheck", {RowOperand{16, 0}}, (n + 3) / 4) * 4;
  if (range_bytes) {
    const int64_t align = int64_t(binding_alignment(ctx_.caps()) / sizeof(float));
    per = std::min(per, std::max(align, int64_t(range_bytes / sizeof(float)) / align * align));
  }
  const vk::Pipeline& storage = ctx_.pipelines().get("nn/nonfinite");
  if (per < n) ctx_.note_split("nonfinite");
  bool fallback = false;  // noted once per call
  for (int64_t first = 0; first < n;) {
    const int64_t count = std::min<int64_t>(n - first, per);
    vk::BufferView range = t.buffer().sub(VkDeviceSize(first) * sizeof(float), VkDeviceSize(count) * sizeof(float));
    range.size = (range.size + 15) / 16 * 16;  // read as vec4s (views are >= 64-byte aligned, padding in-allocation)
    struct {
      uint32_t n, base, slot;
    } push{uint32_t(count), uint32_t(first), slot};
    const Grid g = grid_1d(ctx_.caps(), div_up(div_up(count, 4), kRun), kLocal);
    if (texel_inputs(ctx_.caps()) && texel_view_ok(ctx_, range, 16))
      rec.dispatch(ctx_.pipelines().get("nn/nonfinite_tex4"), {vk::Binding(range, VK_FORMAT_R32G32B32A32_UINT), result_.view()},
                   &push, sizeof push, g.x, g.y, 1, "nonfinite");
    else {
      if (texel_inputs(ctx_.caps()) && !fallback) ctx_.note_split("nonfinite (storage fallback)");
      fallback = true;
      rec.dispatch(storage, {range, result_.view()}, &push, sizeof push, g.x, g.y, 1, "nonfinite");
    }
    first += count;
  }
}

std::vector<NonFiniteHit> NonFiniteCheck::hits() const {
  std::vector<NonFiniteHit> out;
  const auto* r = reinterpret_cast<const uint32_t*>(result_.mapped());
  for (size_t i = 0; i < used_.size(); ++i)
    if (r[2 * i] != 0) out.push_back({used_[i].what, used_[i].shape, r[2 * i], int64_t(r[2 * i + 1])});
  return out;
}

void require_finite(vk::Context& ctx, const std::vector<std::pair<const Tensor*, std::string>>& tensors,
                    const std::string& hint) {
  NonFiniteCheck check(ctx, std::max<int>(1, int(tensors.size())));
  run_now(ctx, [&](vk::Recorder& rec) {
    for (const auto& [t, what] : tensors) check.record(rec, *t, what);
  });
  const auto hits = check.hits();
  if (!hits.empty()) throw Error(hits.front().message() + (hint.empty() ? "" : "; " + hint));
}

}  // namespace dvs::ops
