// What every convolution kernel path of ops_conv.cpp (the implicit-GEMM families, the shifted GEMM of
// ops_conv_shifted.cpp) and the input repack (ops_conv_pack.cpp) share: one call's description, the limits it plans
// against, the source rows and columns an output range reads, and the internal-error helpers.
#pragma once
#include <algorithm>
#include <cstdint>
#include <string>

#include "dvs/error.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/tensor.hpp"
#include "vk/device_info.hpp"

namespace dvs::ops::conv {

[[noreturn]] inline void fail(const char* op, const std::string& what) {
  throw Error(std::string("internal: ") + op + ": " + what);
}
inline void expect(bool ok, const char* op, const std::string& what) {
  if (!ok) fail(op, what);
}
inline uint32_t u32(const char* op, int64_t v) {
  if (v < 0 || v > int64_t(UINT32_MAX)) fail(op, "size " + std::to_string(v) + " out of range");
  return uint32_t(v);
}

// The shaders' code of a weight or bias dtype: 0 f32, 1 f16, 2 bf16.
inline uint32_t weight_code(const char* op, DType t) {
  switch (t) {
    case DType::f32: return 0;
    case DType::f16: return 1;
    case DType::bf16: return 2;
    default: fail(op, std::string("weights must be f32, f16 or bf16, got ") + dtype_name(t));
  }
}

// The bias's binding, its range widened to whole words (16-bit biases are read as uints); without a bias, x's
// first word (any aligned buffer: never read).
inline vk::BufferView bias_binding(const Tensor& x, const Tensor* bias) {
  vk::BufferView v = bias ? bias->buffer() : x.buffer();
  v.size = bias ? (v.size + 3) / 4 * 4 : 4;
  return v;
}

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

// The limits one convolution plans against (the ones in force: the device's, or lower under DVS_LIMITS).
struct ConvLimits {
  uint64_t storage = 0, r32 = 0, rgba = 0, align = 4, groups_x = 0, groups_y = 0, groups_z = 0, groups_1d = 0;
};
inline ConvLimits conv_limits(const vk::DeviceCaps& caps) {
  ConvLimits l;
  l.storage = caps.max_storage_buffer_range;
  l.r32 = binding_capacity(caps, 4);
  l.rgba = binding_capacity(caps, 16);
  l.align = binding_alignment(caps);
  l.groups_x = caps.max_workgroup_count[0];
  l.groups_y = caps.max_workgroup_count[1];
  l.groups_z = caps.max_workgroup_count[2];
  l.groups_1d = max_groups_1d(caps);
  return l;
}

// Source rows [first, end) that output rows [o0, o1) read (empty when they read only padding).
struct RowSpan {
  int64_t first = 0, end = 0;
};
inline RowSpan source_span(const ConvJob& j, int64_t o0, int64_t o1, int64_t pad, int64_t k, int64_t n) {
  int64_t up = j.upsample ? 2 : 1;
  int64_t lo = std::max<int64_t>(o0 * j.stride - pad, 0);
  int64_t hi = std::min<int64_t>((o1 - 1) * j.stride - pad + k - 1, up * n - 1);
  if (hi < lo) return {};
  return {lo / up, hi / up + 1};
}
inline RowSpan source_rows(const ConvJob& j, int64_t oh0, int64_t oh1) {
  return source_span(j, oh0, oh1, j.pad_top, j.kh, j.h);
}
// Source columns [first, end) that output columns [ow0, ow1) read.
inline RowSpan source_cols(const ConvJob& j, int64_t ow0, int64_t ow1) {
  return source_span(j, ow0, ow1, j.pad_left, j.kw, j.w);
}

}  // namespace dvs::ops::conv
