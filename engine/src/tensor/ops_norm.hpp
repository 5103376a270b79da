// Normalisations, all with fp32 statistics (two-pass: mean, then mean of squared deviations; two-level
// block partials merged with Chan's formula for GroupNorm's large groups). Weights and biases may be
// stored f32, bf16 or f16 (both of one layer in the same dtype); activations are f32. Outputs are
// allocated by the caller and may be the input tensor itself (in place).
// Tensors larger than one binding or the grid are walked in chunks, one dispatch each with the same per-row /
// per-group arithmetic: row chunks (layernorm, head_layernorm, rmsnorm; a row itself must fit one binding),
// GroupNorm statistics over chunks of whole groups and its apply pass over chunks of (b, c) planes.
#pragma once
#include <cstdint>

#include "tensor/dispatch.hpp"

namespace dvs::ops {

// adaLN modulation y = norm(x) * (1 + scale) + shift with per-batch vectors read from a table [B, W] (e.g.
// the Linear(SiLU(temb)) output, chunks addressed by column offset). x rows are [B, seq_len] tokens;
// tokens [0, split) use set 0 and tokens [split, seq_len) set 1. CogVideoXLayerNormZero on [text; video]:
// split = text length, set 0 = (enc_shift, enc_scale), set 1 = (shift, scale). One set: split = 0.
struct Modulation {
  Tensor table;  // f32 [B, W]
  int64_t seq_len = 0, split = 0;
  int64_t shift_col[2] = {0, 0}, scale_col[2] = {0, 0};
};

// How layernorm and rmsnorm map rows to invocations is the device's DeviceTuning::norm_row_per_invocation
// (kernel_tuning.hpp): one invocation per row on CPU drivers (lavapipe: barriers and shared memory cost
// more than re-reading a cache-hot row), one workgroup per row elsewhere. Tests and benchmarks force each
// mapping with ScopedTuningOverride("norm_row_per_invocation=on|off").

// LayerNorm over the last dim D of x [..., D]. weight/bias [D] (both or neither: no affine); mod optional. y f32,
// or f16 (the input of GEMMs on tensor cores: ops::gemm_activation_dtype) where D and the modulation columns are
// multiples of 4; each f16 value is the f32 result rounded to nearest even.
void layernorm(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& weight, const Tensor& bias,
               float eps, const Modulation* mod = nullptr);

// Per-head LayerNorm of q or k inside a fused buffer x [rows, row_stride] (f32): heads*head_dim columns from
// col_offset, each head normalised over head_dim, affine [head_dim] shared by heads (or none). y has x's
// shape and layout (columns outside the slice are not written); y may be x.
void head_layernorm(vk::Recorder& rec, const Tensor& x, const Tensor& y, int64_t heads, int64_t head_dim,
                    int64_t col_offset, const Tensor& weight, const Tensor& bias, float eps = 1e-6f);

// q, k or v for the flash attention kernels, in the layout and type they read best: from x [B, L, H·D] f32 (a linear
// layer's output, token-major, contiguous) to y [B, H, L, D] head-major, f16 (rounded to nearest even: the tensor
// cores' operand type) or f32, each (token, head) slice of D columns through, in diffusers' order, the per-head
// LayerNorm (`norm`: weight/bias [D] or neither, eps) and RoPE on tokens [rope_first, rope_first + n) of every batch
// element, n the tables' rows (`rope`: cos/sin f32 [n, D], diffusers' interleaved pairs, as ops::rope). One pass:
// x read once, y written once (instead of head_layernorm, rope and a cast over f32). D a multiple of 4, at most 256;
// y (and the tables) within one binding each (the attention that reads y needs that too); x is walked in row chunks.
struct AttentionHeadsOptions {
  bool norm = false;
  Tensor norm_weight, norm_bias;
  float eps = 1e-6f;
  bool rope = false;
  Tensor cos, sin;
  int64_t rope_first = 0;
};
void attention_heads(vk::Recorder& rec, const Tensor& x, const Tensor& y, int64_t heads,
                     const AttentionHeadsOptions& options);

// RMSNorm (T5): y = weight * x / sqrt(mean(x^2) + eps) over the last dim D of x [..., D].
void rmsnorm(vk::Recorder& rec, const Tensor& x, const Tensor& y, const Tensor& weight, float eps = 1e-6f);

// GroupNorm on x [B, C, ...] (VAE: [B, C, F, H, W]): statistics per (b, group of C/groups channels) over all
// the group's elements; affine gamma/beta [C] (or none); optional SiLU after. scratch: f32 of
// groupnorm_scratch_elems() elements.
int64_t groupnorm_scratch_elems(const Shape& x_shape, int64_t groups);
void groupnorm(vk::Recorder& rec, const Tensor& x, const Tensor& y, int64_t groups, const Tensor& gamma,
               const Tensor& beta, float eps, bool silu, const Tensor& scratch);

}  // namespace dvs::ops
