#include "tensor/ops_conv_weights.hpp"

#include <array>

#include "dvs/error.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

[[noreturn]] void fail(const char* op, const std::string& what) { throw Error(std::string("internal: ") + op + ": " + what); }

uint32_t u32(const char* op, int64_t v) {
  if (v < 0 || v > int64_t(UINT32_MAX)) fail(op, "size " + std::to_string(v) + " out of range");
  return uint32_t(v);
}

struct Dims {
  int64_t cout = 0, cin = 0, taps = 1;
};
Dims dims_of(const char* op, const Shape& s) {
  if (s.size() != 2 && s.size() != 4 && s.size() != 5)
    fail(op, "weights [" + shape_str(s) + "] must be [Cout, Cin, (kt,) kh, kw]");
  Dims d{s[0], s[1], 1};
  for (size_t i = 2; i < s.size(); ++i) d.taps *= s[i];
  return d;
}

int64_t round8(int64_t c) { return (c + 7) / 8 * 8; }

}  // namespace

std::string ConvWeights::describe() const {
  return packed_ ? "packed conv weights [" + shape_str(packed_->shape) + "] " + dtype_name(packed_->packed.dtype())
                 : stored_->describe();
}

Shape packed_conv_weights_shape(const Shape& w) {
  const Dims d = dims_of("pack_conv_weights", w);
  return {d.cout, d.taps * round8(d.cin)};
}

void pack_conv_weights(vk::Recorder& rec, const Tensor& w, const Tensor& packed) {
  const char* op = "pack_conv_weights";
  if (packed.dtype() != w.dtype() || packed.shape() != packed_conv_weights_shape(w.shape()))
    fail(op, "packed " + packed.describe() + " must be [" + shape_str(packed_conv_weights_shape(w.shape())) + "] " +
                 dtype_name(w.dtype()) + " for weights " + w.describe());
  const Dims d = dims_of(op, w.shape());
  pack_conv_weight_slice(rec, op, ConvWeights(w), 0, d.cout, 0, d.cin, round8(d.cin), packed.buffer());
}

PackedConvWeights packed_conv_weights_now(vk::Context& ctx, const Tensor& w, const std::string& what) {
  PackedConvWeights p{Tensor::empty(ctx, packed_conv_weights_shape(w.shape()), w.dtype(), what + " (packed)"), w.shape()};
  run_now(ctx, [&](vk::Recorder& rec) { pack_conv_weights(rec, w, p.packed); });
  return p;
}

void pack_conv_weight_slice(vk::Recorder& rec, const char* op, const ConvWeights& w, int64_t co0, int64_t ng,
                            int64_t ci0, int64_t cc, int64_t cpc, const vk::BufferView& dst) {
  const vk::DeviceCaps& caps = rec.context().caps();
  const Dims d = dims_of(op, w.shape());
  const DType dt = w.dtype();
  if (dt != DType::f32 && dt != DType::f16 && dt != DType::bf16)
    fail(op, std::string("weights must be f32, f16 or bf16, got ") + dtype_name(dt));
  const uint32_t wdt = dt == DType::f32 ? 0 : dt == DType::f16 ? 1 : 2;
  const int64_t per = wdt == 0 ? 1 : 2, eb = wdt == 0 ? 4 : 2, taps = d.taps;
  if (co0 < 0 || ng < 1 || co0 + ng > d.cout || ci0 < 0 || cc < 1 || ci0 + cc > d.cin || cpc % 8 != 0 || cpc < cc)
    fail(op, "slice out of range of " + w.describe());
  // Source strides (elements): the stored [Cout, Cin, taps] or the packed [Cout, taps, CP].
  const int64_t full_cp = round8(d.cin);
  const int64_t s_co = w.packed() ? taps * full_cp : d.cin * taps, s_ci = w.packed() ? 1 : taps;
  const int64_t s_tap = w.packed() ? full_cp : 1;
  const uint64_t storage = caps.max_storage_buffer_range, align = binding_alignment(caps);
  const uint64_t groups = max_groups_1d(caps) * 64;
  const int64_t items_per_co = cpc / per;  // one invocation per output channel and packed word of one tap
  // Source elements [first, end) that output channels [c, c + n) of the slice read, and dst's words they write.
  auto src_span = [&](int64_t c, int64_t n) {
    return std::pair<uint64_t, uint64_t>(uint64_t((co0 + c) * s_co + ci0 * s_ci),
                                         uint64_t((co0 + c + n - 1) * s_co + (ci0 + cc - 1) * s_ci + (taps - 1) * s_tap + 1));
  };
  auto fits = [&](int64_t n) {
    auto [first, end] = src_span(0, n);
    return (end - first) * uint64_t(eb) + align + 4 <= storage && uint64_t(n * taps * cpc * eb) + align <= storage &&
           uint64_t(n * items_per_co) <= groups;
  };
  int64_t step = ng;
  while (step > 1 && !fits(step)) --step;
  if (!fits(step)) fail(op, "one output channel's weights exceed one binding");
  const std::array<uint32_t, 1> spec = {wdt};
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/conv_pack_weights", spec);
  const int64_t words_per_co = taps * cpc / per;
  for_each_chunk(ng, step, [&](int64_t c0, int64_t n) {
    auto [first, end] = src_span(c0, n);
    uint32_t src_base = 0, dst_base = 0;
    const vk::BufferView src = aligned_view(w.tensor().buffer(), first * eb, end * eb, align, uint32_t(eb), src_base);
    const vk::BufferView out = aligned_view(dst, uint64_t(c0 * words_per_co) * 4, uint64_t((c0 + n) * words_per_co) * 4,
                                            align, 4, dst_base);
    struct {
      uint32_t items, s_co, s_ci, s_tap, taps, cp, co0, ci0, cc, item0, src_base, dst_base;
    } pc{u32(op, n * items_per_co), u32(op, s_co), u32(op, s_ci), u32(op, s_tap), u32(op, taps), u32(op, cpc),
         u32(op, co0), u32(op, ci0), u32(op, cc), u32(op, c0 * items_per_co), src_base, dst_base};
    const Grid g = grid_1d(caps, n * items_per_co, 64);
    rec.dispatch(pipe, {src, out}, &pc, sizeof pc, g.x, g.y, 1, std::string(op) + "_pack_weights");
  });
}

}  // namespace dvs::ops
