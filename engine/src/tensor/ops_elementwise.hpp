// Elementwise fp32 ops and dtype casts. All record into a vk::Recorder; outputs are allocated by the caller
// with the shape of x. The output may be the input tensor itself (in place).
//
// Broadcasting of the second operand y (numpy rules, restricted to what one index formula covers): y's
// shape, right-aligned to x's, must be 1 or equal to x on every axis, and its non-1 axes must form one
// contiguous run of x's axes. That covers same shape, a scalar ([] or [1]), a row vector [D] over [.., D]
// and a per-channel vector [C, 1, 1] over [.., C, H, W] (reshape a [C] tensor to [C, 1, 1] first).
#pragma once
#include "tensor/tensor.hpp"
#include "vk/context.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops {

// Unary, f32 -> f32.
void scale(vk::Recorder& rec, const Tensor& x, const Tensor& y, float a, float b = 0.0f);  // y = a·x + b
void silu(vk::Recorder& rec, const Tensor& x, const Tensor& y);                            // x·sigmoid(x)
void gelu_tanh(vk::Recorder& rec, const Tensor& x, const Tensor& y);  // PyTorch gelu(approximate='tanh')
void gelu_erf(vk::Recorder& rec, const Tensor& x, const Tensor& y);   // PyTorch nn.GELU(): 0.5·x·(1 + erf(x/√2))
void relu(vk::Recorder& rec, const Tensor& x, const Tensor& y);       // max(x, 0)
void clamp(vk::Recorder& rec, const Tensor& x, const Tensor& y, float lo, float hi);

// Binary, f32, y broadcast as described above; z has x's shape.
void add(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& z);  // z = x + y
void sub(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& z);  // z = x - y
void mul(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& z);  // z = x · y
void axpby(vk::Recorder& rec, float a, const Tensor& x, float b, const Tensor& y, const Tensor& z);  // z = a·x + b·y

// Fused scale and shift: z = x·(scale + scale_offset) + shift, scale and shift of one shape broadcast over x
// as above. Per-channel AdaIN with [C,1,1] statistics; adaLN modulation x·(1 + scale) + shift over [tokens, D]
// with scale_offset = 1. Tolerance: one fp32 FMA or mul+add (the device may fuse).
void scale_shift(vk::Recorder& rec, const Tensor& x, const Tensor& scale, const Tensor& shift, const Tensor& z,
                 float scale_offset = 0.0f);

// Dtype conversion between f32, f16, bf16 and i32 (same element count; shapes may differ).
// To f16/bf16: round to nearest even, NaN kept, overflow to ±Inf. f32 -> i32: truncation toward zero,
// saturating, NaN -> 0. i32 -> f32: nearest float. A 16-bit tensor with an odd element count must have 2 bytes
// of slack after it (every Allocator/Arena allocation has); their contents are preserved.
void cast(vk::Recorder& rec, const Tensor& x, const Tensor& y);

// Whether ops with vec4-sized work (elementwise, concat/split, permute, nonfinite) read their inputs through
// texel buffers when the views allow (faster on lavapipe), or through storage buffers (GPUs): the device's
// DeviceTuning::eltwise_texel_inputs; tests and benchmarks force either path with
// ScopedTuningOverride("eltwise_texel_inputs=on|off").
bool texel_inputs(const vk::DeviceCaps& caps);
// For op implementations: whether `v` can be bound as a uniform texel buffer of `texel_bytes`-sized texels
// (offset alignment, whole texels, maxTexelBufferElements).
bool texel_view_ok(vk::Context& ctx, const vk::BufferView& v, uint32_t texel_bytes);

}  // namespace dvs::ops
