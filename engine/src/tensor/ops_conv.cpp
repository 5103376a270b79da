#include "tensor/ops_conv.hpp"

#include <algorithm>
#include <array>
#include <string>

#include "dvs/error.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

constexpr uint32_t kConvLocal = 64;      // shaders/nn/conv.comp local_size_x
constexpr uint32_t kMaxCachePrefix = 4;  // shaders/nn/conv3d_cache.comp MAXP

[[noreturn]] void fail(const char* op, const std::string& what) { throw Error(std::string("internal: ") + op + ": " + what); }

void expect(bool ok, const char* op, const std::string& what) {
  if (!ok) fail(op, what);
}

uint32_t weight_code(const char* op, DType t) {
  switch (t) {
    case DType::f32: return 0;
    case DType::f16: return 1;
    case DType::bf16: return 2;
    default: fail(op, std::string("weights must be f32, f16 or bf16, got ") + dtype_name(t));
  }
}

// Packed 16-bit tensors are read as uints: widen the bound range to whole words.
vk::BufferView word_view(const Tensor& t) {
  vk::BufferView v = t.buffer();
  v.size = (v.size + 3) / 4 * 4;
  return v;
}

uint32_t u32(const char* op, int64_t v) {
  if (v < 0 || v > int64_t(UINT32_MAX)) fail(op, "size " + std::to_string(v) + " out of range");
  return uint32_t(v);
}

// Register block per invocation (output channels x output pixels of a row). CPU drivers (narrow
// subgroups, loads executed per lane: lavapipe) want tall blocks that reuse every load many times and
// share weights through subgroup broadcasts; GPUs want few registers per thread and load the uniform
// weights directly. On lavapipe the 16x16 block runs ~1.3x faster than 8x8 but its pipeline takes ~8x
// longer to compile (seconds), so small convolutions (tests, tiny models) use 8x8.
struct ConvBlock {
  uint32_t co = 8, px = 8;
  bool bcast = true;
};
ConvRegisterBlock g_block_override;

ConvBlock conv_block(const vk::Context& ctx, double macs) {
  const auto& caps = ctx.caps();
  bool cpu_like = caps.subgroup_size >= 8 && caps.subgroup_size <= 16;
  ConvBlock b = cpu_like ? (macs >= double(1u << 27) ? ConvBlock{16, 16, true} : ConvBlock{8, 8, true})
                         : ConvBlock{8, 4, false};
  if (g_block_override.channels) b.co = g_block_override.channels;
  if (g_block_override.pixels) b.px = g_block_override.pixels;
  if (g_block_override.share_weights >= 0) b.bcast = g_block_override.share_weights == 1;
  if (caps.subgroup_size < 8) b.bcast = false;  // the broadcast scheme needs 8 lanes per subgroup
  return b;
}

// Everything conv.comp needs for a [B, Cin, F, H, W] input.
struct ConvJob {
  int64_t b = 1, cin = 1, frames = 1, h = 1, w = 1;
  int64_t cout = 1, kt = 1, kh = 1, kw = 1, stride = 1;
  int64_t pad_top = 0, pad_left = 0, ho = 1, wo = 1, frames_out = 1, prefix = 0;
  int64_t ys_b = 0, ys_c = 0, ys_f = 0, ys_h = 0, ys_w = 0;
  bool upsample = false;   // read the nearest x2 spatial upsampling of the input (h, w: input sizes)
  uint32_t time_map = 0;   // output frame -> input frame for kt = 1 (see conv.comp)
};

struct ConvPush {
  uint32_t cin, cout, src_frames, h, w, ho, wo;
  int32_t pad_top, pad_left;
  uint32_t prefix, src_shift, tap_mode, has_bias, tiles_w, frames, fo_begin;
  uint32_t ys_b, ys_c, ys_f, ys_h, ys_w;
  uint32_t time_map;
};
static_assert(sizeof(ConvPush) <= 128);

// One pass of conv.comp over output frames [fo_begin, fo_begin + frames) reading `src`.
struct ConvPass {
  const Tensor* src;
  int64_t src_frames, src_shift, fo_begin, frames;
  uint32_t tap_mode;  // 0 all taps, 1 taps on the prefix only, 2 taps on the input only (resumes from y)
  bool add_bias;
};

void check_bias(const char* op, const Tensor& w, const Tensor* bias, int64_t cout) {
  if (!bias) return;
  expect(bias->dtype() == w.dtype(), op, "bias " + bias->describe() + " must have the weights' dtype " + dtype_name(w.dtype()));
  expect(bias->numel() == cout, op, "bias " + bias->describe() + " must hold Cout = " + std::to_string(cout) + " values");
}

void record_conv_pass(vk::Recorder& rec, const char* op, const ConvJob& j, const ConvPass& pass, const Tensor& w,
                      const Tensor* bias, const Tensor& y) {
  if (pass.frames <= 0) return;
  uint32_t wdt = weight_code(op, w.dtype());
  double macs = double(j.b * pass.frames * j.ho * j.wo) * double(j.cout) * double(j.cin * j.kt * j.kh * j.kw);
  ConvBlock blk = conv_block(rec.context(), macs);
  std::array<uint32_t, 9> spec = {u32(op, j.kt), u32(op, j.kh), u32(op, j.kw), u32(op, j.stride), wdt,
                                  blk.bcast ? 1u : 0u, blk.co, blk.px, j.upsample ? 1u : 0u};
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/conv", spec);

  ConvPush pc{};
  pc.cin = u32(op, j.cin);
  pc.cout = u32(op, j.cout);
  pc.src_frames = u32(op, pass.src_frames);
  pc.h = u32(op, j.h);
  pc.w = u32(op, j.w);
  pc.ho = u32(op, j.ho);
  pc.wo = u32(op, j.wo);
  pc.pad_top = int32_t(j.pad_top);
  pc.pad_left = int32_t(j.pad_left);
  pc.prefix = u32(op, j.prefix);
  pc.src_shift = u32(op, pass.src_shift);
  pc.tap_mode = pass.tap_mode;
  pc.has_bias = bias && pass.add_bias ? 1 : 0;
  pc.tiles_w = div_up(j.wo, blk.px);
  pc.frames = u32(op, pass.frames);
  pc.fo_begin = u32(op, pass.fo_begin);
  pc.ys_b = u32(op, j.ys_b);
  pc.ys_c = u32(op, j.ys_c);
  pc.ys_f = u32(op, j.ys_f);
  pc.ys_h = u32(op, j.ys_h);
  pc.ys_w = u32(op, j.ys_w);
  pc.time_map = j.time_map;

  int64_t gx = div_up(j.ho * int64_t(pc.tiles_w), kConvLocal);
  int64_t gy = div_up(j.cout, blk.co);
  int64_t gz = j.b * pass.frames;
  if (gx > 65535 || gy > 65535 || gz > 65535)
    fail(op, "grid " + std::to_string(gx) + "x" + std::to_string(gy) + "x" + std::to_string(gz) +
                 " exceeds 65535 workgroups per dimension; tile the input");
  if (gx == 0 || gy == 0) return;

  // Input and weights are read through texel buffers, whose size limit (2^27 elements on lavapipe and
  // on NVIDIA) can be below the storage-buffer range.
  uint64_t max_texels = rec.context().caps().max_texel_buffer_elements;
  for (const Tensor* t : {pass.src, &w})
    if (max_texels && uint64_t(t->numel()) > max_texels)
      fail(op, t->describe() + " exceeds the device's texel-buffer limit of " + std::to_string(max_texels) +
                   " elements; split the convolution (spatial tiles or fewer frames per batch)");
  VkFormat wfmt = wdt == 0 ? VK_FORMAT_R32_UINT : VK_FORMAT_R16_UINT;
  vk::BufferView bv = bias ? word_view(*bias) : word_view(w);
  rec.dispatch(pipe, {vk::Binding(pass.src->buffer(), VK_FORMAT_R32_SFLOAT), vk::Binding(w.buffer(), wfmt), bv, y.buffer()},
               &pc, sizeof pc, uint32_t(gx), uint32_t(gy), uint32_t(gz), op);
}

// Weight shape as (Cout, Cin, kt, kh, kw) from a 4-D or 5-D tensor.
std::array<int64_t, 5> kernel_dims(const char* op, const Tensor& w) {
  const Shape& s = w.shape();
  if (s.size() == 5) return {s[0], s[1], s[2], s[3], s[4]};
  if (s.size() == 4) return {s[0], s[1], 1, s[2], s[3]};
  if (s.size() == 2) return {s[0], s[1], 1, 1, 1};
  fail(op, "weights " + w.describe() + " must be [Cout, Cin, (kt,) kh, kw]");
}

}  // namespace

void set_conv_register_block(const ConvRegisterBlock& block) {
  if (block.channels > 64 || block.pixels > 64) fail("set_conv_register_block", "block too large");
  g_block_override = block;
}

Shape conv2d_shape(const Shape& x, const Shape& w, const Conv2dParams& p) {
  const char* op = "conv2d";
  expect(x.size() == 4 || x.size() == 5, op, "input must be [N, C, H, W] or [B, C, F, H, W], got [" + shape_str(x) + "]");
  expect(w.size() == 4 || (w.size() == 5 && w[2] == 1), op, "weights must be [Cout, Cin, kh, kw], got [" + shape_str(w) + "]");
  int64_t kh = w[w.size() - 2], kw = w[w.size() - 1];
  int64_t h = x[x.size() - 2], wd = x[x.size() - 1];
  expect(p.stride >= 1, op, "stride must be >= 1");
  int64_t hp = h + p.pad_top + p.pad_bottom, wp = wd + p.pad_left + p.pad_right;
  expect(hp >= kh && wp >= kw, op, "padded input smaller than the kernel");
  int64_t ho = (hp - kh) / p.stride + 1, wo = (wp - kw) / p.stride + 1;
  int64_t cout = w[0];
  if (x.size() == 4) return p.channels_last_out ? Shape{x[0], ho, wo, cout} : Shape{x[0], cout, ho, wo};
  return p.channels_last_out ? Shape{x[0], x[2], ho, wo, cout} : Shape{x[0], cout, x[2], ho, wo};
}

void conv2d(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor* bias, const Tensor& y,
            const Conv2dParams& p) {
  const char* op = "conv2d";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect_shape(op, "y", y, conv2d_shape(x.shape(), w.shape(), p));
  auto k = kernel_dims(op, w);
  ConvJob j;
  if (x.rank() == 4) {
    j.b = x.dim(0), j.cin = x.dim(1), j.frames = 1, j.h = x.dim(2), j.w = x.dim(3);
  } else {
    j.b = x.dim(0), j.cin = x.dim(1), j.frames = x.dim(2), j.h = x.dim(3), j.w = x.dim(4);
  }
  expect(k[1] == j.cin, op, "weights " + w.describe() + " do not match input channels of " + x.describe());
  j.cout = k[0], j.kt = 1, j.kh = k[3], j.kw = k[4], j.stride = p.stride;
  j.pad_top = p.pad_top, j.pad_left = p.pad_left;
  expect(p.pad_top >= 0 && p.pad_left >= 0 && p.pad_bottom >= 0 && p.pad_right >= 0, op, "negative padding");
  j.ho = (j.h + p.pad_top + p.pad_bottom - j.kh) / p.stride + 1;
  j.wo = (j.w + p.pad_left + p.pad_right - j.kw) / p.stride + 1;
  j.frames_out = j.frames, j.prefix = 0;
  int64_t plane = j.ho * j.wo;
  if (p.channels_last_out) {
    j.ys_w = j.cout, j.ys_h = j.wo * j.cout, j.ys_c = 1, j.ys_f = plane * j.cout, j.ys_b = j.frames * plane * j.cout;
  } else {
    j.ys_w = 1, j.ys_h = j.wo, j.ys_f = plane, j.ys_c = j.frames * plane, j.ys_b = j.cout * j.frames * plane;
  }
  check_bias(op, w, bias, j.cout);
  record_conv_pass(rec, op, j, {&x, j.frames, 0, 0, j.frames, 0, true}, w, bias, y);
}

Shape causal_conv3d_cache_shape(const Shape& x, const Shape& w) {
  expect(x.size() == 5 && w.size() == 5, "causal_conv3d", "cache shape needs 5-D input and weights");
  return {x[0], x[1], w[2] - 1, x[3], x[4]};
}

void causal_conv3d(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor* bias, const Tensor& y,
                   const Tensor* cache_in, const Tensor* cache_out) {
  const char* op = "causal_conv3d";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect(x.rank() == 5, op, "input must be [B, C, F, H, W], got " + x.describe());
  auto k = kernel_dims(op, w);
  ConvJob j;
  j.b = x.dim(0), j.cin = x.dim(1), j.frames = x.dim(2), j.h = x.dim(3), j.w = x.dim(4);
  expect(k[1] == j.cin, op, "weights " + w.describe() + " do not match input channels of " + x.describe());
  j.cout = k[0], j.kt = k[2], j.kh = k[3], j.kw = k[4], j.stride = 1;
  expect(j.kh % 2 == 1 && j.kw % 2 == 1 && j.kt >= 1, op, "kernel " + w.describe() + " must have odd kh, kw");
  j.pad_top = (j.kh - 1) / 2, j.pad_left = (j.kw - 1) / 2;
  j.ho = j.h, j.wo = j.w, j.frames_out = j.frames, j.prefix = j.kt - 1;
  expect_shape(op, "y", y, {j.b, j.cout, j.frames, j.h, j.w});
  expect(j.prefix <= int64_t(kMaxCachePrefix), op, "time kernel too long");
  Shape cache_shape = {j.b, j.cin, j.prefix, j.h, j.w};
  if (j.prefix == 0) expect(!cache_in && !cache_out, op, "a kt = 1 convolution has no cache");
  if (cache_in) {
    expect_dtype(op, "cache_in", *cache_in, DType::f32);
    expect_shape(op, "cache_in", *cache_in, cache_shape);
  }
  if (cache_out) {
    expect_dtype(op, "cache_out", *cache_out, DType::f32);
    expect_shape(op, "cache_out", *cache_out, cache_shape);
  }
  int64_t plane = j.h * j.w;
  j.ys_w = 1, j.ys_h = j.w, j.ys_f = plane, j.ys_c = j.frames * plane, j.ys_b = j.cout * j.frames * plane;
  check_bias(op, w, bias, j.cout);
  if (!cache_in) {
    // First frame batch: the prefix replicates frame 0 (src frame = max(tp - prefix, 0)).
    record_conv_pass(rec, op, j, {&x, j.frames, j.prefix, 0, j.frames, 0, true}, w, bias, y);
  } else {
    // Frames whose taps all lie on the input, then the first `prefix` frames in two passes: the cache
    // taps (partial sum into y) and the input taps resuming from it.
    int64_t head = std::min(j.prefix, j.frames);
    record_conv_pass(rec, op, j, {&x, j.frames, j.prefix, head, j.frames - head, 0, true}, w, bias, y);
    record_conv_pass(rec, op, j, {cache_in, j.prefix, 0, 0, head, 1, false}, w, bias, y);
    record_conv_pass(rec, op, j, {&x, j.frames, j.prefix, 0, head, 2, true}, w, bias, y);
  }

  if (cache_out && j.frames > 0) {
    struct {
      uint32_t columns, hw, frames, prefix, use_prev;
    } pc{u32(op, j.b * j.cin * plane), u32(op, plane), u32(op, j.frames), u32(op, j.prefix), cache_in ? 1u : 0u};
    std::array<uint32_t, 1> spec = {kMaxCachePrefix};
    const vk::Pipeline& pipe = rec.context().pipelines().get("nn/conv3d_cache", spec);
    Grid g = grid_1d(pc.columns, 64);
    if (pc.columns == 0) return;
    rec.dispatch(pipe, {x.buffer(), cache_in ? cache_in->buffer() : x.buffer(), cache_out->buffer()}, &pc, sizeof pc,
                 g.x, g.y, 1, "causal_conv3d_cache");
  }
}

void conv1x1(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor* bias, const Tensor& y) {
  const char* op = "conv1x1";
  auto k = kernel_dims(op, w);
  expect(k[2] == 1 && k[3] == 1 && k[4] == 1, op, "weights " + w.describe() + " are not 1x1x1");
  expect(x.rank() == 5, op, "input must be [B, C, F, H, W], got " + x.describe());
  Tensor w5 = w.reshape({k[0], k[1], 1, 1, 1});
  causal_conv3d(rec, x, w5, bias, y, nullptr, nullptr);
}

int64_t downsample_time_frames(int64_t frames) { return frames % 2 == 1 ? 1 + (frames - 1) / 2 : frames / 2; }

void avgpool_time_pairs(vk::Recorder& rec, const Tensor& x, const Tensor& y) {
  const char* op = "avgpool_time_pairs";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect(x.rank() == 5, op, "input must be [B, C, F, H, W], got " + x.describe());
  int64_t fo = downsample_time_frames(x.dim(2));
  expect_shape(op, "y", y, {x.dim(0), x.dim(1), fo, x.dim(3), x.dim(4)});
  struct {
    uint32_t hw, frames, frames_out, bc_begin;
  } pc{u32(op, x.dim(3) * x.dim(4)), u32(op, x.dim(2)), u32(op, fo), 0};
  int64_t bc = x.dim(0) * x.dim(1);
  if (y.numel() == 0) return;
  bool vec4 = pc.hw % 4 == 0;  // whole vec4s per plane (and 16-byte aligned planes)
  if (vec4) pc.hw /= 4;
  expect(fo <= 65535 && div_up(pc.hw, 64) <= 65535, op, "frame count or plane too large: " + x.describe());
  const vk::Pipeline& pipe = rec.context().pipelines().get(vec4 ? "nn/avgpool_time_vec4" : "nn/avgpool_time");
  for (int64_t first = 0; first < bc; first += 65535) {
    pc.bc_begin = uint32_t(first);
    rec.dispatch(pipe, {x.buffer(), y.buffer()}, &pc, sizeof pc, div_up(pc.hw, 64), uint32_t(fo),
                 uint32_t(std::min<int64_t>(65535, bc - first)), op);
  }
}

void upsample_nearest(vk::Recorder& rec, const Tensor& x, const Tensor& y, bool keep_first_frame) {
  const char* op = "upsample_nearest";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect(x.rank() == 5 && y.rank() == 5, op, "x and y must be [B, C, F, H, W]: " + x.describe() + ", " + y.describe());
  expect(x.dim(0) == y.dim(0) && x.dim(1) == y.dim(1), op, "batch and channels must match: " + x.describe() + " -> " + y.describe());
  if (keep_first_frame)
    expect((x.dim(2) >= 2 && y.dim(2) >= 2) || x.dim(2) == y.dim(2), op,
           "keep_first_frame needs at least 2 frames on both sides: " + x.describe() + " -> " + y.describe());
  expect(y.numel() == 0 || x.numel() > 0, op, "empty input");
  struct {
    uint32_t frames, h, w, frames_out, ho, wo, keep_first, z_begin;
  } pc{u32(op, x.dim(2)), u32(op, x.dim(3)), u32(op, x.dim(4)), u32(op, y.dim(2)), u32(op, y.dim(3)), u32(op, y.dim(4)),
       keep_first_frame && x.dim(2) != y.dim(2) ? 1u : 0u, 0};
  if (y.numel() == 0) return;
  expect(pc.ho <= 65535 && div_up(pc.wo, 64) <= 65535, op, "output too large: " + y.describe());
  int64_t zs = y.dim(0) * y.dim(1) * y.dim(2);
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/upsample_nearest");
  for (int64_t first = 0; first < zs; first += 65535) {
    pc.z_begin = uint32_t(first);
    rec.dispatch(pipe, {x.buffer(), y.buffer()}, &pc, sizeof pc, div_up(pc.wo, 64), pc.ho,
                 uint32_t(std::min<int64_t>(65535, zs - first)), op);
  }
}

Shape upsample2x_shape(const Shape& x, bool compress_time) {
  expect(x.size() == 5, "upsample2x", "input must be [B, C, F, H, W], got [" + shape_str(x) + "]");
  int64_t f = x[2];
  int64_t fo = !compress_time || f <= 1 ? f : (f % 2 == 1 ? 1 + 2 * (f - 1) : 2 * f);
  return {x[0], x[1], fo, 2 * x[3], 2 * x[4]};
}

void upsample2x(vk::Recorder& rec, const Tensor& x, const Tensor& y, bool compress_time) {
  const char* op = "upsample2x";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  expect_shape(op, "y", y, upsample2x_shape(x.shape(), compress_time));
  int64_t f = x.dim(2);
  uint32_t time_mode = !compress_time || f <= 1 ? 0 : (f % 2 == 1 ? 1 : 2);
  struct {
    uint32_t frames, h, w, frames_out, time_mode, z_begin;
  } pc{u32(op, f), u32(op, x.dim(3)), u32(op, x.dim(4)), u32(op, y.dim(2)), time_mode, 0};
  if (y.numel() == 0) return;
  expect(pc.h <= 65535 && div_up(pc.w, 64) <= 65535, op, "input too large: " + x.describe());
  int64_t zs = y.dim(0) * y.dim(1) * y.dim(2);
  const vk::Pipeline& pipe = rec.context().pipelines().get("nn/upsample2x");
  for (int64_t first = 0; first < zs; first += 65535) {
    pc.z_begin = uint32_t(first);
    rec.dispatch(pipe, {x.buffer(), y.buffer()}, &pc, sizeof pc, div_up(pc.w, 64), pc.h,
                 uint32_t(std::min<int64_t>(65535, zs - first)), op);
  }
}

void upsample2x_conv3x3(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor* bias, const Tensor& y,
                        bool compress_time) {
  const char* op = "upsample2x_conv3x3";
  expect_dtype(op, "x", x, DType::f32);
  expect_dtype(op, "y", y, DType::f32);
  Shape up = upsample2x_shape(x.shape(), compress_time);
  auto k = kernel_dims(op, w);
  expect(k[2] == 1 && k[3] == 3 && k[4] == 3 && k[1] == x.dim(1), op,
         "weights " + w.describe() + " must be [Cout, " + std::to_string(x.dim(1)) + ", 3, 3]");
  expect_shape(op, "y", y, {up[0], k[0], up[2], up[3], up[4]});
  ConvJob j;
  j.b = x.dim(0), j.cin = x.dim(1), j.frames = x.dim(2), j.h = x.dim(3), j.w = x.dim(4);
  j.cout = k[0], j.kt = 1, j.kh = 3, j.kw = 3, j.stride = 1, j.pad_top = 1, j.pad_left = 1;
  j.ho = up[3], j.wo = up[4], j.frames_out = up[2], j.prefix = 0;
  j.upsample = true;
  int64_t f = x.dim(2);
  j.time_map = !compress_time || f <= 1 ? 0 : (f % 2 == 1 ? 1 : 2);
  int64_t plane = j.ho * j.wo;
  j.ys_w = 1, j.ys_h = j.wo, j.ys_f = plane, j.ys_c = j.frames_out * plane, j.ys_b = j.cout * j.frames_out * plane;
  check_bias(op, w, bias, j.cout);
  record_conv_pass(rec, op, j, {&x, j.frames, 0, 0, j.frames_out, 0, true}, w, bias, y);
}

}  // namespace dvs::ops
