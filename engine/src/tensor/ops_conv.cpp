#include "tensor/ops_conv.hpp"

#include <algorithm>
#include <array>
#include <string>

#include "dvs/error.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "vk/context.hpp"

namespace dvs::ops {
namespace {

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

ConvRegisterBlock g_block_override;
uint64_t g_chunk_bytes_override = 0;

// Everything a convolution needs, for a [B, Cin, F, H, W] input.
struct ConvJob {
  int64_t b = 1, cin = 1, frames = 1, h = 1, w = 1;
  int64_t cout = 1, kt = 1, kh = 1, kw = 1, stride = 1;
  int64_t pad_top = 0, pad_left = 0, ho = 1, wo = 1, frames_out = 1, prefix = 0;
  int64_t ys_b = 0, ys_c = 0, ys_f = 0, ys_h = 0, ys_w = 0;
  bool upsample = false;     // read the nearest x2 spatial upsampling of the input (h, w: input sizes)
  uint32_t time_mode = 0;    // padded frame -> source frame, see conv_pack_input.comp
  const Tensor* cache = nullptr;  // time_mode 3: the previous batch's last `prefix` frames
};

struct GemmPush {
  uint32_t m, n, cp, kt, kh, kw, stride, up, wo, rows, oh0;
  int32_t pad_top, pad_left;
  uint32_t in_h, in_w, src_r0, src_rows, src_w, zero_texel, y_base;
  uint32_t ys_f, ys_h, ys_w, ys_c, has_bias;
};
static_assert(sizeof(GemmPush) <= 128);

struct PackInputPush {
  uint32_t texels, cp4, c, src_frames, h, w, batch, tp0, frames, r0, rows, prefix, time_mode;
};

struct PackWeightsPush {
  uint32_t words, cin, taps, cp;
};

void check_bias(const char* op, const Tensor& w, const Tensor* bias, int64_t cout) {
  if (!bias) return;
  expect(bias->dtype() == w.dtype(), op, "bias " + bias->describe() + " must have the weights' dtype " + dtype_name(w.dtype()));
  expect(bias->numel() == cout, op, "bias " + bias->describe() + " must hold Cout = " + std::to_string(cout) + " values");
}

void check_texels(const char* op, const vk::Context& ctx, const Tensor& t, uint64_t texels) {
  uint64_t max_texels = ctx.caps().max_texel_buffer_elements;
  if (max_texels && texels > max_texels)
    fail(op, t.describe() + " exceeds the device's texel-buffer limit of " + std::to_string(max_texels) +
                 " elements; split the convolution (spatial tiles or fewer frames per batch)");
}

constexpr uint64_t kScratchInputCap = 128ull << 20;  // bytes; see ConvScratch

// f32 elements of a convolution's staging: the whole repacked input (capped) and the repacked weights.
ConvScratchSize scratch_size(int64_t frames_out, int64_t kt, int64_t h, int64_t w, int64_t cin, int64_t cout,
                             int64_t taps) {
  const int64_t cp = (cin + 7) / 8 * 8;
  uint64_t input = uint64_t(frames_out + kt - 1) * uint64_t(h * w) * uint64_t(cp) * 4 + uint64_t(cp) * 4;
  uint64_t weights = uint64_t(cout * taps * cp) * 4;  // f32, the largest weight dtype
  return {int64_t(std::min(input, kScratchInputCap) / 4), int64_t(weights / 4)};
}

// Source rows [first, end) that output rows [oh0, oh1) read (empty when they read only padding).
struct RowSpan {
  int64_t first = 0, end = 0;
};
RowSpan source_rows(const ConvJob& j, int64_t oh0, int64_t oh1) {
  int64_t up = j.upsample ? 2 : 1;
  int64_t lo = std::max<int64_t>(oh0 * j.stride - j.pad_top, 0);
  int64_t hi = std::min<int64_t>((oh1 - 1) * j.stride - j.pad_top + j.kh - 1, up * j.h - 1);
  if (hi < lo) return {};
  return {lo / up, hi / up + 1};
}

// Packed weights [Cout, taps, CP] in scratch slot 1, recorded once per call.
vk::BufferView pack_weights(vk::Recorder& rec, const char* op, const ConvJob& j, const Tensor& w, uint32_t wdt, int64_t cp,
                            const ConvScratch* given) {
  vk::Context& ctx = rec.context();
  int64_t taps = j.kt * j.kh * j.kw;
  int64_t words = j.cout * taps * cp / (wdt == 0 ? 1 : 2);
  uint64_t bytes = uint64_t(words) * 4;
  expect(bytes <= ctx.caps().max_storage_buffer_range, op,
         "packed weights of " + w.describe() + " exceed maxStorageBufferRange");
  check_texels(op, ctx, w, uint64_t(words) / 4);
  if (given)
    expect(uint64_t(given->weights.bytes()) >= bytes, op, "weights scratch " + given->weights.describe() + " is too small");
  vk::BufferView packed = given ? given->weights.buffer() : rec.scratch(1, bytes, "convolution weights (repacked)");
  packed.size = bytes;
  PackWeightsPush pc{u32(op, words), u32(op, j.cin), u32(op, taps), u32(op, cp)};
  std::array<uint32_t, 1> spec = {wdt};
  Grid g = grid_1d(words, 64);
  rec.dispatch(ctx.pipelines().get("nn/conv_pack_weights", spec), {word_view(w), packed}, &pc, sizeof pc, g.x, g.y, 1,
               std::string(op) + "_pack_weights");
  return packed;
}

// The convolution: the weights are repacked once, then per batch item and chunk of output frames (and,
// when one frame is too large, of output rows) the chunk's input is repacked channels-last and the GEMM
// kernel runs over it. Chunks are sized so the packed input stays within one storage binding and one
// texel view, and the grid within 65535 workgroups per dimension.
void record_conv(vk::Recorder& rec, const char* op, const ConvJob& j, const Tensor& x, const Tensor& w,
                 const Tensor* bias, const Tensor& y, const ConvScratch* given) {
  if (j.b == 0 || j.frames_out == 0 || j.ho == 0 || j.wo == 0 || j.cout == 0) return;
  vk::Context& ctx = rec.context();
  const vk::DeviceCaps& caps = ctx.caps();
  uint32_t wdt = weight_code(op, w.dtype());
  check_texels(op, ctx, x, uint64_t(x.numel()));
  if (j.cache) check_texels(op, ctx, *j.cache, uint64_t(j.cache->numel()));
  const int64_t cp = (j.cin + 7) / 8 * 8, up = j.upsample ? 2 : 1;

  GemmTile tile = conv_tile(caps, w.dtype(), j.frames_out * j.ho * j.wo, j.cout);
  if (g_block_override.rows) tile.rows = g_block_override.rows;
  if (g_block_override.cols) tile.cols = g_block_override.cols;
  if (g_block_override.k_unroll) tile.k_unroll = g_block_override.k_unroll;
  if (g_block_override.lanes >= 0) tile.lanes = std::max(g_block_override.lanes, gemm_lanes(caps));
  const int64_t tile_m = int64_t(tile.sg_m) * tile.rows, tile_n = int64_t(8 / tile.sg_m) * 8 * tile.cols;
  expect(div_up(j.cout, tile_n) <= 65535, op, "too many output channels for one dispatch");

  // Chunk budget: one storage binding (the pack writes it), one texel view of RGBA32F texels.
  uint64_t cap = caps.max_storage_buffer_range;
  if (caps.max_texel_buffer_elements) cap = std::min<uint64_t>(cap, caps.max_texel_buffer_elements * 16);
  cap = std::min(cap, kScratchInputCap);
  if (given) cap = std::min<uint64_t>(cap, uint64_t(given->input.bytes()));
  if (g_chunk_bytes_override) cap = std::min<uint64_t>(cap, g_chunk_bytes_override);
  const uint64_t pixel_bytes = uint64_t(cp) * 4, max_m = uint64_t(65535) * uint64_t(tile_m);
  // Bytes of a chunk of nfo output frames and r output rows, wherever the rows lie (interior rows read the
  // most source rows: the span of r rows plus the kernel, halved and rounded out when upsampling).
  auto chunk_bytes = [&](int64_t nfo, int64_t r) {
    int64_t span = (r - 1) * j.stride + j.kh;
    int64_t src_rows = r == j.ho ? source_rows(j, 0, j.ho).end - source_rows(j, 0, j.ho).first
                                 : std::min(j.h, up == 1 ? span : (span - 1) / 2 + 2);
    return uint64_t(nfo + j.kt - 1) * uint64_t(src_rows) * uint64_t(j.w) * pixel_bytes + pixel_bytes;
  };
  int64_t chunk_frames = 0, chunk_rows = j.ho;
  for (int64_t n = j.frames_out; n >= 1 && chunk_frames == 0; --n)
    if (chunk_bytes(n, j.ho) <= cap && uint64_t(n * j.ho * j.wo) <= max_m) chunk_frames = n;
  if (chunk_frames == 0) {  // one frame at a time, split over rows
    chunk_frames = 1;
    chunk_rows = 0;
    for (int64_t r = j.ho; r >= 1 && chunk_rows == 0; --r)
      if (chunk_bytes(1, r) <= cap && uint64_t(r * j.wo) <= max_m) chunk_rows = r;
    expect(chunk_rows >= 1, op, "one output row of " + y.describe() + " needs more than the device's binding limit (" +
                                    std::to_string(cap) + " bytes) of repacked input; tile the input spatially");
  }

  vk::BufferView packed_w = pack_weights(rec, op, j, w, wdt, cp, given);
  const vk::BufferView bias_view = bias ? word_view(*bias) : word_view(w);
  const int64_t steps = cp / 8;
  const uint32_t ku = steps % 4 == 0 ? std::min<uint32_t>(4, uint32_t(tile.k_unroll)) : (steps % 2 == 0 ? std::min<uint32_t>(2, uint32_t(tile.k_unroll)) : 1u);
  std::array<uint32_t, 6> gemm_spec = {uint32_t(tile.rows), uint32_t(tile.cols), wdt, uint32_t(tile.lanes),
                                       uint32_t(tile.sg_m), std::max(ku, 1u)};
  const vk::Pipeline& gemm =
      ctx.pipelines().get(tile.lanes == 2 ? "nn/conv_gemm_nosubgroup" : "nn/conv_gemm", gemm_spec);
  const vk::Pipeline& pack = ctx.pipelines().get("nn/conv_pack_input");
  const Tensor& cache_src = j.cache ? *j.cache : x;

  for (int64_t b = 0; b < j.b; ++b)
    for (int64_t fo0 = 0; fo0 < j.frames_out; fo0 += chunk_frames)
      for (int64_t oh0 = 0; oh0 < j.ho; oh0 += chunk_rows) {
        int64_t nfo = std::min(chunk_frames, j.frames_out - fo0), oh1 = std::min(j.ho, oh0 + chunk_rows);
        RowSpan rs = source_rows(j, oh0, oh1);
        int64_t src_rows = rs.end - rs.first, packed_frames = nfo + j.kt - 1;
        int64_t texels = packed_frames * src_rows * j.w * (cp / 4);
        expect(uint64_t(texels + cp / 4) * 16 <= cap, op, "chunk planning error");  // guards the bound above
        const uint64_t packed_bytes = uint64_t(texels + cp / 4) * 16;
        vk::BufferView packed_x = given ? given->input.buffer() : rec.scratch(0, packed_bytes, "convolution input chunk (repacked)");
        packed_x.size = packed_bytes;

        PackInputPush pp{u32(op, texels), u32(op, cp / 4), u32(op, j.cin), u32(op, j.frames), u32(op, j.h), u32(op, j.w),
                         u32(op, b), u32(op, fo0), u32(op, packed_frames), u32(op, rs.first), u32(op, src_rows),
                         u32(op, j.prefix), j.time_mode};
        Grid g = grid_1d(texels + cp / 4, 64);
        rec.dispatch(pack,
                     {vk::Binding(x.buffer(), VK_FORMAT_R32_SFLOAT), vk::Binding(cache_src.buffer(), VK_FORMAT_R32_SFLOAT),
                      packed_x},
                     &pp, sizeof pp, g.x, g.y, 1, std::string(op) + "_pack_input");

        GemmPush pc{};
        int64_t m = nfo * (oh1 - oh0) * j.wo;
        pc.m = u32(op, m);
        pc.n = u32(op, j.cout);
        pc.cp = u32(op, cp);
        pc.kt = u32(op, j.kt), pc.kh = u32(op, j.kh), pc.kw = u32(op, j.kw);
        pc.stride = u32(op, j.stride), pc.up = u32(op, up);
        pc.wo = u32(op, j.wo), pc.rows = u32(op, oh1 - oh0), pc.oh0 = u32(op, oh0);
        pc.pad_top = int32_t(j.pad_top), pc.pad_left = int32_t(j.pad_left);
        pc.in_h = u32(op, up * j.h), pc.in_w = u32(op, up * j.w);
        pc.src_r0 = u32(op, rs.first), pc.src_rows = u32(op, src_rows), pc.src_w = u32(op, j.w);
        pc.zero_texel = u32(op, texels);
        pc.y_base = u32(op, b * j.ys_b + fo0 * j.ys_f + oh0 * j.ys_h);
        pc.ys_f = u32(op, j.ys_f), pc.ys_h = u32(op, j.ys_h), pc.ys_w = u32(op, j.ys_w), pc.ys_c = u32(op, j.ys_c);
        pc.has_bias = bias ? 1 : 0;
        uint32_t gx = div_up(m, tile_m), gy = div_up(j.cout, tile_n);
        rec.dispatch(gemm,
                     {vk::Binding(packed_x, VK_FORMAT_R32G32B32A32_SFLOAT),
                      vk::Binding(packed_w, VK_FORMAT_R32G32B32A32_UINT), bias_view, y.buffer()},
                     &pc, sizeof pc, gx, gy, 1, op);
      }
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
  if (block.rows < 0 || block.rows > 16 || block.cols < 0 || block.cols > 8 || block.lanes > 2 ||
      !(block.k_unroll == 0 || block.k_unroll == 1 || block.k_unroll == 2 || block.k_unroll == 4))
    fail("set_conv_register_block", "block out of range (rows 1..16, cols 1..8, lanes -1..2, k_unroll 0, 1, 2, 4)");
  g_block_override = block;
}

void set_conv_chunk_bytes(uint64_t bytes) { g_chunk_bytes_override = bytes; }

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
            const Conv2dParams& p, const ConvScratch* scratch) {
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
  record_conv(rec, op, j, x, w, bias, y, scratch);
}

Shape causal_conv3d_cache_shape(const Shape& x, const Shape& w) {
  expect(x.size() == 5 && w.size() == 5, "causal_conv3d", "cache shape needs 5-D input and weights");
  return {x[0], x[1], w[2] - 1, x[3], x[4]};
}

void causal_conv3d(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor* bias, const Tensor& y,
                   const Tensor* cache_in, const Tensor* cache_out, const ConvScratch* scratch) {
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
  // The prefix replicates frame 0 (first frame batch) or is the previous batch's cache; either way the
  // taps are summed in the same order, so a clip run in frame batches equals the whole clip bit for bit.
  j.time_mode = cache_in ? 3 : 0;
  j.cache = cache_in;
  record_conv(rec, op, j, x, w, bias, y, scratch);

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

void conv1x1(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor* bias, const Tensor& y,
             const ConvScratch* scratch) {
  const char* op = "conv1x1";
  auto k = kernel_dims(op, w);
  expect(k[2] == 1 && k[3] == 1 && k[4] == 1, op, "weights " + w.describe() + " are not 1x1x1");
  expect(x.rank() == 5, op, "input must be [B, C, F, H, W], got " + x.describe());
  Tensor w5 = w.reshape({k[0], k[1], 1, 1, 1});
  causal_conv3d(rec, x, w5, bias, y, nullptr, nullptr, scratch);
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
                        bool compress_time, const ConvScratch* scratch) {
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
  j.time_mode = !compress_time || f <= 1 ? 0 : (f % 2 == 1 ? 1 : 2);
  int64_t plane = j.ho * j.wo;
  j.ys_w = 1, j.ys_h = j.wo, j.ys_f = plane, j.ys_c = j.frames_out * plane, j.ys_b = j.cout * j.frames_out * plane;
  check_bias(op, w, bias, j.cout);
  record_conv(rec, op, j, x, w, bias, y, scratch);
}

ConvScratchSize conv2d_scratch(const Shape& x, const Shape& w) {
  expect(x.size() == 4 || x.size() == 5, "conv2d", "input must be [N, C, H, W] or [B, C, F, H, W]");
  int64_t frames = x.size() == 5 ? x[2] : 1;
  return scratch_size(frames, 1, x[x.size() - 2], x[x.size() - 1], x[1], w[0], w[w.size() - 2] * w[w.size() - 1]);
}

ConvScratchSize causal_conv3d_scratch(const Shape& x, const Shape& w) {
  expect(x.size() == 5, "causal_conv3d", "input must be [B, C, F, H, W]");
  int64_t kt = w.size() == 5 ? w[2] : 1, taps = 1;
  for (size_t i = 2; i < w.size(); ++i) taps *= w[i];
  return scratch_size(x[2], kt, x[3], x[4], x[1], w[0], taps);
}

ConvScratchSize upsample2x_conv3x3_scratch(const Shape& x, const Shape& w, bool compress_time) {
  Shape up = upsample2x_shape(x, compress_time);
  return scratch_size(up[2], 1, x[3], x[4], x[1], w[0], 9);
}

}  // namespace dvs::ops
