#include <limits>
#include "tensor/ops_elementwise.hpp"

#include <algorithm>
#include <numeric>
#include <string>

#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

constexpr uint32_t kLocal = 64, kMaxGroups = 4096;  // grid-stride loops: enough groups, few dispatch tasks

// Grid-stride loops need no more groups than the limit allows: fewer just loop more.
uint32_t groups_for(const vk::DeviceCaps& caps, int64_t items) {
  return std::clamp<uint32_t>(div_up(items, kLocal), 1, std::min(kMaxGroups, caps.max_workgroup_count[0]));
}

// Elements per chunk of a flat walk over f32 operands: whole vec4s, each operand's chunk within one binding
// (the texel path is then chosen per chunk). >= n: one chunk, the unsplit call.
int64_t flat_chunk(const vk::DeviceCaps& caps, const char* op, int64_t n) {
  return rows_per_chunk(caps, op, {RowOperand{16, 0}}, (n + 3) / 4) * 4;
}

Tensor flat_sub(const Tensor& t, int64_t first, int64_t count) {
  return Tensor::on(t.buffer().sub(VkDeviceSize(first) * 4, VkDeviceSize(count) * 4), {count}, DType::f32);
}

void check_count(const char* op, const Tensor& t) {
  if (t.numel() >= int64_t(UINT32_MAX) - 4) throw Error(std::string("internal: ") + op + ": " + t.describe() + " is too large");
}

// Texel-buffer inputs: texelFetch is ~2-3x cheaper than a storage-buffer load on lavapipe (docs/design.md §8), so
// where the device's tuning says so (DeviceTuning::eltwise_texel_inputs) vec4-sized work reads x (and y, s,
// t) through uniform texel buffers whenever the views allow it: offset aligned to
// minTexelBufferOffsetAlignment and few enough texels for maxTexelBufferElements.
VkDeviceSize texel_offset_alignment(const vk::DeviceCaps& caps) {
  return std::max<VkDeviceSize>(1, caps.min_texel_buffer_offset_alignment);
}

bool texel_ok(vk::Context& ctx, const Tensor& t, int64_t texels) {
  return t.buffer().offset % texel_offset_alignment(ctx.caps()) == 0 && uint64_t(texels) <= ctx.caps().max_texel_buffer_elements;
}

}  // namespace

bool texel_view_ok(vk::Context& ctx, const vk::BufferView& v, uint32_t texel_bytes) {
  return v.offset % texel_offset_alignment(ctx.caps()) == 0 && v.size % texel_bytes == 0 &&
         v.size / texel_bytes <= ctx.caps().max_texel_buffer_elements;
}

namespace {

vk::Binding rgba(const Tensor& t) { return vk::Binding(t.buffer(), VK_FORMAT_R32G32B32A32_SFLOAT); }
vk::Binding r32(const Tensor& t) { return vk::Binding(t.buffer(), VK_FORMAT_R32_SFLOAT); }

enum class UnaryOp : uint32_t { affine = 0, silu = 1, gelu_tanh = 2, clamp = 3, gelu_erf = 4 };

// `vec4_body`: run whole vec4s through the vec4 shader (decided for the whole tensor, so that every chunk of
// a split call computes each element with the same shader as the unsplit call).
void unary_range(vk::Recorder& rec, const char* op, UnaryOp kind, const Tensor& x, const Tensor& y, float a, float b,
                 bool vec4_body) {
  const int64_t n = x.numel();
  vk::Context& ctx = rec.context();
  const uint32_t spec[] = {uint32_t(kind)};
  struct {
    uint32_t n;
    float a, b;
    uint32_t first;
  } push{0, a, b, 0};
  const int64_t body = n / 4 * 4;
  if (vec4_body && body > 0) {  // whole vec4s; an odd-sized tensor adds a scalar tail below
    const Tensor xb = body == n ? x : Tensor::on(x.buffer().sub(0, VkDeviceSize(body) * 4), {body}, DType::f32);
    const Tensor yb = body == n ? y : Tensor::on(y.buffer().sub(0, VkDeviceSize(body) * 4), {body}, DType::f32);
    const bool texel = texel_inputs(ctx.caps()) && texel_ok(ctx, xb, body / 4);
    push.n = uint32_t(body / 4);
    const vk::Pipeline& p = ctx.pipelines().get(texel ? "nn/eltwise_unary_tex4" : "nn/eltwise_unary_vec4", spec);
    rec.dispatch(p, {texel ? rgba(xb) : vk::Binding(xb.buffer()), yb.buffer()}, &push, sizeof push,
                 groups_for(ctx.caps(), body / 4), 1, 1, op);
    if (body == n) return;
    push.first = uint32_t(body);
  }
  push.n = uint32_t(n);
  const int64_t rest = n - push.first;
  rec.dispatch(ctx.pipelines().get("nn/eltwise_unary", spec), {x.buffer(), y.buffer()}, &push, sizeof push,
               groups_for(ctx.caps(), rest), 1, 1, op);
}

// Flat element chunks, each run as an unsplit call on sub-views.
void unary(vk::Recorder& rec, const char* op, UnaryOp kind, const Tensor& x, const Tensor& y, float a, float b) {
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect_shape(op, "y", y, x.shape());
  check_count(op, x);
  const int64_t n = x.numel();
  if (n == 0) return;
  const bool vec4_body = n % 4 == 0 || n >= 4 * int64_t(kLocal);  // small odd tensors: one scalar dispatch
  const int64_t chunk = flat_chunk(rec.context().caps(), op, n);
  if (chunk >= n) return unary_range(rec, op, kind, x, y, a, b, vec4_body);
  rec.context().note_split(op);
  for_each_chunk(n, chunk, [&](int64_t first, int64_t count) {
    unary_range(rec, op, kind, flat_sub(x, first, count), flat_sub(y, first, count), a, b, vec4_body);
  });
}

// y broadcast over x as y[(e / inner) % C]; see the header for the accepted shapes.
struct Broadcast {
  int64_t C = 1, inner = 1;
};

Broadcast broadcast_of(const char* op, const Shape& xs, const Shape& ys) {
  auto fail = [&] {
    throw Error(std::string("internal: ") + op + ": cannot broadcast [" + shape_str(ys) + "] over [" + shape_str(xs) +
                "] (allowed: same shape, scalar, [D] over [.., D], [C,1,..] over [.., C, ..])");
  };
  if (ys.size() > xs.size()) {
    // Leading 1s beyond x's rank are harmless.
    for (size_t i = 0; i < ys.size() - xs.size(); ++i)
      if (ys[i] != 1) fail();
  }
  const size_t r = xs.size();
  Shape y(r, 1);
  for (size_t i = 0; i < std::min(r, ys.size()); ++i) y[r - 1 - i] = ys[ys.size() - 1 - i];
  int first = -1, last = -1;
  for (size_t d = 0; d < r; ++d) {
    if (y[d] != 1 && y[d] != xs[d]) fail();
    if (y[d] != 1) {
      if (first < 0) first = int(d);
      last = int(d);
    }
  }
  Broadcast b;
  if (first < 0) return b;  // scalar
  for (int d = first; d <= last; ++d) {
    if (y[size_t(d)] != xs[size_t(d)]) fail();  // a 1 inside the run
    b.C *= xs[size_t(d)];
  }
  for (size_t d = size_t(last) + 1; d < r; ++d) b.inner *= xs[d];
  return b;
}

// Which broadcast indexing a shader runs (MODE in shaders/nn/eltwise_broadcast.glsl) and the per-stride
// advance of its (channel, inner) counters.
struct BcastPlan {
  uint32_t mode = 5, C = 1, inner = 1, step_c = 0, step_r = 0, base = 0;
};

// `same`: y has x's shape (MODE 0). `base`: the element of y's broadcast period where x's element 0 falls
// (non-zero for a chunk that starts mid-period).
BcastPlan plan_broadcast(Broadcast bc, int64_t n, bool same, bool vec4, uint32_t groups, uint32_t base) {
  BcastPlan pl;
  pl.base = base;
  if (!vec4) {
    pl.mode = same ? 0 : 5;
  } else {
    if (bc.C == 1) bc.inner = n;  // a scalar: one value for every vec4
    if (same) pl.mode = 0;
    else if (bc.inner == 1 && bc.C % 4 == 0) pl.mode = 1;
    else if (bc.inner % 4 == 0) pl.mode = 2;
    else if (bc.inner >= 4) pl.mode = 3;
    else if (bc.inner == 1 && bc.C >= 4) pl.mode = 4;
    else pl.mode = 5;
    const int64_t per_stride = int64_t(groups) * kLocal * 4;  // elements a grid stride advances
    pl.step_r = uint32_t(per_stride % bc.inner);
    pl.step_c = uint32_t((per_stride / bc.inner) % bc.C);
  }
  pl.C = uint32_t(bc.C);
  pl.inner = uint32_t(bc.inner);
  return pl;
}

// One chunk of a broadcast op: x's elements [first, first + count); the operand is bound as its elements
// [y_first, y_first + bc.C) (the whole operand unless it is larger than one binding), read as
// y[((e + base) / bc.inner) % bc.C].
struct BroadcastChunk {
  int64_t first = 0, count = 0;
  bool same = false;
  uint32_t base = 0;
  Broadcast bc;
  int64_t y_first = 0;
  bool y_whole = true;
};

// A broadcast op walked in flat chunks of x: a same-shape operand is chunked along; a smaller one stays bound
// whole (row and per-channel vectors) with the chunk's start in its period as `base`. An operand larger than
// one binding (the transformer's positional table added over the batch) is bound per chunk as the window of
// its elements the chunk reads: chunks then stop at period ends, so that window is contiguous.
// Whether the op runs vec4 shaders: x whole vec4s, and a windowed operand's period too (its chunks stop at
// period ends).
bool broadcast_vec4(const vk::DeviceCaps& caps, const char* op, int64_t n, const Broadcast& bc, const Tensor& operand) {
  if (n % 4 != 0) return false;
  const bool windowed = !(bc.inner == 1 && bc.C == n) && flat_chunk(caps, op, n) < n &&
                        operand.bytes() > binding_capacity(caps, 0);
  return !windowed || (bc.C * bc.inner) % 4 == 0;
}

template <class F>
void for_each_broadcast_chunk(vk::Context& ctx, const char* op, int64_t n, const Broadcast& bc,
                              const Tensor& operand, bool vec4, F&& fn) {
  const bool same = bc.inner == 1 && bc.C == n;
  const int64_t chunk = flat_chunk(ctx.caps(), op, n);
  if (chunk >= n) return fn(BroadcastChunk{0, n, same, 0u, bc, 0, true});
  ctx.note_split(op);
  const int64_t period = bc.C * bc.inner;
  if (same || operand.bytes() <= binding_capacity(ctx.caps(), 0)) {
    for_each_chunk(n, chunk, [&](int64_t first, int64_t count) {
      fn(BroadcastChunk{first, count, same, same ? 0u : uint32_t(first % period), bc, 0, true});
    });
    return;
  }
  // Window starts aligned for a binding offset and for vec4 reads of the operand; x's chunks start at period
  // ends, so those must be binding offsets too (true of every real shape: widths are multiples of 4).
  const int64_t align = std::lcm<int64_t>(int64_t(binding_alignment(ctx.caps()) / 4), 4);
  if (period % align != 0)
    throw Error(std::string("internal: ") + op + ": broadcast operand " + operand.describe() + " is larger than one "
                "binding and its period of " + std::to_string(period) + " elements is not a multiple of " +
                std::to_string(align) + " (the binding alignment)");
  const int64_t window_most = int64_t(binding_capacity(ctx.caps(), 0) / 4) / align * align;
  for (int64_t pos = 0; pos < n;) {
    const int64_t in_period = pos % period;
    const int64_t c0 = in_period / bc.inner, c0a = c0 / align * align;
    int64_t count = std::min({chunk, period - in_period, n - pos, (c0a + window_most) * bc.inner - in_period});
    if (vec4) count = count / 4 * 4;  // whole vec4s (period and window ends are multiples of 4)
    const int64_t c_last = (in_period + count - 1) / bc.inner;
    const int64_t window = std::min(bc.C - c0a, (c_last - c0a + 1 + 3) / 4 * 4);
    fn(BroadcastChunk{pos, count, false, uint32_t(in_period - c0a * bc.inner), Broadcast{window, bc.inner}, c0a, false});
    pos += count;
  }
}

// The operand as one chunk binds it.
Tensor operand_of(const BroadcastChunk& c, const Tensor& y) {
  if (c.same) return flat_sub(y, c.first, c.count);
  return c.y_whole ? y : flat_sub(y, c.y_first, c.bc.C);
}

enum class BinaryOp : uint32_t { axpby = 0, mul = 1 };

void binary_range(vk::Recorder& rec, const char* op, BinaryOp kind, float alpha, const Tensor& x, float beta,
                  const Tensor& y, const Tensor& z, Broadcast bc, bool same, bool vec4, uint32_t base) {
  vk::Context& ctx = rec.context();
  const int64_t n = x.numel();
  if (same) bc = Broadcast{n, 1};
  const int64_t units = vec4 ? n / 4 : n;
  const uint32_t groups = groups_for(ctx.caps(), units);
  const BcastPlan pl = plan_broadcast(bc, n, same, vec4, groups, base);
  const bool y_vec4 = pl.mode <= 1;  // y read as whole vec4s
  const bool texel = vec4 && texel_inputs(ctx.caps()) && texel_ok(ctx, x, n / 4) &&
                     texel_ok(ctx, y, y_vec4 ? y.numel() / 4 : y.numel());
  const char* shader = !vec4 ? "nn/eltwise_binary"
                       : texel ? "nn/eltwise_binary_tex4"
                       : y_vec4 ? "nn/eltwise_binary_vec4"
                                : "nn/eltwise_binary_vec4_bcast";
  struct {
    uint32_t n, C, inner, step_c, step_r;
    float alpha, beta;
    uint32_t base;
  } push{uint32_t(units), pl.C, pl.inner, pl.step_c, pl.step_r, alpha, beta, pl.base};
  const uint32_t spec[] = {uint32_t(kind), pl.mode};
  const vk::Pipeline& p = ctx.pipelines().get(shader, spec);
  if (texel)
    rec.dispatch(p, {rgba(x), y_vec4 ? rgba(y) : r32(y), z.buffer()}, &push, sizeof push, groups, 1, 1, op);
  else
    rec.dispatch(p, {x.buffer(), y.buffer(), z.buffer()}, &push, sizeof push, groups, 1, 1, op);
}

void binary(vk::Recorder& rec, const char* op, BinaryOp kind, float alpha, const Tensor& x, float beta,
            const Tensor& y, const Tensor& z) {
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect_dtype(op, "z", z, DType::f32);
  expect_shape(op, "z", z, x.shape());
  check_count(op, x);
  const Broadcast bc = broadcast_of(op, x.shape(), y.shape());
  const int64_t n = x.numel();
  if (n == 0) return;
  // Decided for the whole tensor: every chunk runs the same shader.
  const bool vec4 = broadcast_vec4(rec.context().caps(), op, n, bc, y);
  for_each_broadcast_chunk(rec.context(), op, n, bc, y, vec4, [&](const BroadcastChunk& c) {
    if (c.count == n) return binary_range(rec, op, kind, alpha, x, beta, y, z, bc, c.same, vec4, c.base);
    binary_range(rec, op, kind, alpha, flat_sub(x, c.first, c.count), beta, operand_of(c, y),
                 flat_sub(z, c.first, c.count), c.bc, c.same, vec4, c.base);
  });
}

void affine_range(vk::Recorder& rec, const char* op, const Tensor& x, const Tensor& s, const Tensor& t,
                  const Tensor& z, float s_offset, Broadcast bc, bool same, bool vec4, uint32_t base) {
  vk::Context& ctx = rec.context();
  const int64_t n = x.numel();
  if (same) bc = Broadcast{n, 1};
  const int64_t units = vec4 ? n / 4 : n;
  const uint32_t groups = groups_for(ctx.caps(), units);
  BcastPlan pl = plan_broadcast(bc, n, same, vec4, groups, base);
  if (vec4 && pl.mode == 0) pl.mode = 1;  // same shape runs as rows of length n
  const bool st_vec4 = vec4 && pl.mode == 1;
  const int64_t st_texels = st_vec4 ? s.numel() / 4 : s.numel();
  const bool texel = vec4 && texel_inputs(ctx.caps()) && texel_ok(ctx, x, n / 4) && texel_ok(ctx, s, st_texels) &&
                     texel_ok(ctx, t, st_texels);
  struct {
    uint32_t n, C, inner, step_c, step_r;
    float s_offset;
    uint32_t base;
  } push{uint32_t(units), pl.C, pl.inner, pl.step_c, pl.step_r, s_offset, pl.base};
  const char* shader = texel ? "nn/eltwise_affine_tex4" : vec4 ? "nn/eltwise_affine_vec4" : "nn/eltwise_affine";
  const uint32_t spec[] = {0, pl.mode};
  const vk::Pipeline& p = ctx.pipelines().get(shader, spec);
  if (texel) {
    auto st = [&](const Tensor& v) { return st_vec4 ? rgba(v) : r32(v); };
    rec.dispatch(p, {rgba(x), st(s), st(t), z.buffer()}, &push, sizeof push, groups, 1, 1, op);
  } else {
    rec.dispatch(p, {x.buffer(), s.buffer(), t.buffer(), z.buffer()}, &push, sizeof push, groups, 1, 1, op);
  }
}

void affine(vk::Recorder& rec, const char* op, const Tensor& x, const Tensor& s, const Tensor& t, const Tensor& z,
            float s_offset) {
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "scale", s, DType::f32);
  expect_dtype(op, "shift", t, DType::f32);
  expect_dtype(op, "z", z, DType::f32);
  expect_shape(op, "z", z, x.shape());
  expect_shape(op, "shift", t, s.shape());
  check_count(op, x);
  const Broadcast bc = broadcast_of(op, x.shape(), s.shape());
  const int64_t n = x.numel();
  if (n == 0) return;
  const bool vec4 = broadcast_vec4(rec.context().caps(), op, n, bc, s);
  for_each_broadcast_chunk(rec.context(), op, n, bc, s, vec4, [&](const BroadcastChunk& c) {
    if (c.count == n) return affine_range(rec, op, x, s, t, z, s_offset, bc, c.same, vec4, c.base);
    affine_range(rec, op, flat_sub(x, c.first, c.count), operand_of(c, s), operand_of(c, t),
                 flat_sub(z, c.first, c.count), s_offset, c.bc, c.same, vec4, c.base);
  });
}

uint32_t cast_code(const char* op, const Tensor& t) {
  switch (t.dtype()) {
    case DType::f32: return 0;
    case DType::f16: return 1;
    case DType::bf16: return 2;
    case DType::i32: return 3;
    default: throw Error(std::string("internal: ") + op + ": unsupported dtype in " + t.describe());
  }
}

// 16-bit data is moved as whole 32-bit words: round the bound range up to a word.
vk::BufferView word_view(const Tensor& t) {
  vk::BufferView v = t.buffer();
  v.size = (v.size + 3) & ~VkDeviceSize(3);
  return v;
}

void cast_range(vk::Recorder& rec, const Tensor& x, const Tensor& y, uint32_t src, uint32_t dst) {
  const int64_t n = x.numel();
  const uint32_t spec[] = {src, dst};
  const bool x8 = n % 8 == 0;  // whole uvec4 loads and stores
  const vk::Pipeline& p = rec.context().pipelines().get(x8 ? "nn/cast_x8" : "nn/cast", spec);
  const uint32_t push = uint32_t(n);
  rec.dispatch(p, {word_view(x), word_view(y)}, &push, sizeof push,
               groups_for(rec.context().caps(), x8 ? n / 8 : (n + 1) / 2), 1, 1, "cast");
}

}  // namespace

bool texel_inputs(const vk::DeviceCaps& caps) { return device_tuning(caps).eltwise_texel_inputs; }

void scale(vk::Recorder& rec, const Tensor& x, const Tensor& y, float a, float b) {
  unary(rec, "scale", UnaryOp::affine, x, y, a, b);
}
void silu(vk::Recorder& rec, const Tensor& x, const Tensor& y) { unary(rec, "silu", UnaryOp::silu, x, y, 0, 0); }
void gelu_tanh(vk::Recorder& rec, const Tensor& x, const Tensor& y) {
  unary(rec, "gelu_tanh", UnaryOp::gelu_tanh, x, y, 0, 0);
}
void gelu_erf(vk::Recorder& rec, const Tensor& x, const Tensor& y) {
  unary(rec, "gelu_erf", UnaryOp::gelu_erf, x, y, 0, 0);
}
void clamp(vk::Recorder& rec, const Tensor& x, const Tensor& y, float lo, float hi) {
  if (!(lo <= hi)) throw Error("internal: clamp: lo " + std::to_string(lo) + " > hi " + std::to_string(hi));
  unary(rec, "clamp", UnaryOp::clamp, x, y, lo, hi);
}
void relu(vk::Recorder& rec, const Tensor& x, const Tensor& y) {
  unary(rec, "relu", UnaryOp::clamp, x, y, 0.0f, std::numeric_limits<float>::infinity());
}

void add(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& z) {
  binary(rec, "add", BinaryOp::axpby, 1.0f, x, 1.0f, y, z);
}
void sub(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& z) {
  binary(rec, "sub", BinaryOp::axpby, 1.0f, x, -1.0f, y, z);
}
void mul(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& z) {
  binary(rec, "mul", BinaryOp::mul, 1.0f, x, 1.0f, y, z);
}
void axpby(vk::Recorder& rec, float a, const Tensor& x, float b, const Tensor& y, const Tensor& z) {
  binary(rec, "axpby", BinaryOp::axpby, a, x, b, y, z);
}

void scale_shift(vk::Recorder& rec, const Tensor& x, const Tensor& scale, const Tensor& shift, const Tensor& z,
                 float scale_offset) {
  affine(rec, "scale_shift", x, scale, shift, z, scale_offset);
}

void cast(vk::Recorder& rec, const Tensor& x, const Tensor& y) {
  const uint32_t src = cast_code("cast", x), dst = cast_code("cast", y);
  if (x.numel() != y.numel())
    throw Error("internal: cast: " + x.describe() + " and " + y.describe() + " differ in element count");
  check_count("cast", x);
  const int64_t n = x.numel();
  if (n == 0) return;
  if (src == dst) {
    rec.copy(x.buffer(), y.buffer(), x.bytes());
    return;
  }
  // Flat chunks of whole 8-element groups (16-bit data stays in whole words); each runs as an unsplit cast.
  const size_t sx = dtype_size(x.dtype()), sy = dtype_size(y.dtype());
  const int64_t chunk =
      rows_per_chunk(rec.context().caps(), "cast", {RowOperand{8 * sx, 0}, RowOperand{8 * sy, 0}}, (n + 7) / 8) * 8;
  if (chunk >= n) return cast_range(rec, x, y, src, dst);
  rec.context().note_split("cast");
  for_each_chunk(n, chunk, [&](int64_t first, int64_t count) {
    cast_range(rec, Tensor::on(x.buffer().sub(first * sx, count * sx), {count}, x.dtype()),
               Tensor::on(y.buffer().sub(first * sy, count * sy), {count}, y.dtype()), src, dst);
  });
}

}  // namespace dvs::ops
