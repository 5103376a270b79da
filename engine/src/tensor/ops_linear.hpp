// Linear layers (GEMM with the weight in PyTorch nn.Linear layout) and their fused epilogues.
//
//   Y[b] = epilogue(X[b] · W[b]ᵀ)     X f32 [M,K] (f16 on the tiled and coopmat families), W [N,K] stored f32,
//                                      f16 or bf16, Y f32 [M,N]
//
// Arithmetic and accumulation are fp32; 16-bit weights are widened in the shader. Any M, N, K work; the
// fast path wants K and the element offsets/strides of X and W to be multiples of 8 (true for every model
// shape) and silently uses a slower scalar path otherwise.
#pragma once
#include <cstdint>

#include "tensor/kernel_tuning.hpp"
#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops {

enum class Activation : uint32_t { none = 0, gelu_tanh = 1, silu = 2, gelu_erf = 3 };

// Optional steps applied to f = X·Wᵀ, each only when its tensor is defined / its option set, in this order:
//   1. f += bias[n]                         bias [N]: f32, f16 or bf16
//   2. f = act(f)                           GELU (tanh approximation, as diffusers' "gelu-approximate";
//                                           or the exact erf form of nn.GELU()) or SiLU
//   3. f = f · (1 + scale[n]) + shift[n]    modulation; scale and shift f32 [N] or [batch, N] (both required)
//   4. f = gate[n] · f                      gate f32 [N] or [batch, N]
//   5. y = residual + f                     residual f32 with Y's shape and layout
// So with gate and residual: y = r + gate ⊙ f (gated residual); with residual only: y = r + f.
// The residual may be Y itself (in-place update): every element is read before it is written by the same
// invocation. No other input may alias Y.
struct LinearEpilogue {
  Tensor bias;
  Activation activation = Activation::none;
  Tensor scale, shift;
  Tensor gate;
  Tensor residual;
  // false: the caller's X or W may exceed fp16 range (|x| > 65504 becomes inf in an fp16 operand), so the
  // tensor-core (coopmat) family, whose operands are fp16, must not be used: a coopmat device then runs the
  // tiled fp32 kernel. (T5's activations exceed fp16 range.)
  bool fp16_operands_ok = true;
};

// A batch of GEMMs over the same tensors with element strides. All sizes in elements.
//   X[b][m][k] = x[b*x_batch_stride + m*x_row_stride + k]
//   W[b][n][k] = w[b*w_batch_stride + n*K + k]           (w_batch_stride 0: one weight shared by the batch)
//   Y[b][m][n] = y[b*y_batch_stride + m*y_row_stride + n]  (the residual uses the same layout)
//   gate/scale/shift[b][n] = v[b*vec_batch_stride + n]     (0: shared by the batch)
// Row strides of 0 mean contiguous rows (K for X, N for Y).
struct LinearShape {
  int64_t batch = 1, m = 0, n = 0, k = 0;
  int64_t x_batch_stride = 0, w_batch_stride = 0, y_batch_stride = 0, vec_batch_stride = 0;
  int64_t x_row_stride = 0, y_row_stride = 0;
};

// Y = epilogue(X·Wᵀ): x [..., K] (leading dimensions flattened into M), w [N, K], y [..., N].
void linear(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor& y, const LinearEpilogue& ep = {});

// Batched / strided form. Tensors are taken as flat element ranges; the shape says how to walk them
// (every element addressed must lie inside its tensor, checked).
// Operands larger than one binding / texel view, or grids over maxComputeWorkGroupCount, are split: batch
// items, then weight rows (Y column slices) when W or a Y row does not fit, then rows of X/Y/residual; each
// chunk is one dispatch of the same kernel (bitwise the unsplit result). K is split (partial sums added
// into Y) only when one row of X/W exceeds a binding and the epilogue has no activation, modulation or gate.
void linear_batched(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor& y, const LinearShape& shape,
                    const LinearEpilogue& ep = {});

// Kernel configuration, chosen per call from the shape, the weight type and the device; exposed for tests
// and benchmarks that pin a variant. A cluster of 8 lanes computes rows x (8·cols) outputs of Y: rows 8 or
// 16 share X rows by subgroup shuffles, rows 1, 2 or 4 (small M) are fetched by every lane; cols 1..8.
// lanes: 0 subgroups of exactly 8 (lavapipe), 1 clusters of 8 inside wider subgroups (GPUs), 2 no subgroup
// operations (shader linalg/linear_nosubgroup). sg_m: clusters of the 64-invocation workgroup along M.
// vectorized: 8-value K steps through RGBA texels; on the coopmat family 16-byte loads of X and W (both fall
// back to element loads when the layout forbids).
// family: texel (the fields above), tiled (linalg/linear_tiled: storage buffers, shared-memory tiles of
// tile_m x tile_n outputs, tile_k K values per step, fp32 FMA; tile_m/n multiples of 16 up to 64) or coopmat
// (linalg/linear_coopmat: the same staging in fp16 feeding VK_KHR_cooperative_matrix, fp32 accumulation;
// its layout, `coopmat`, is the tuning's for the shape: DeviceTuning::linear_coopmat or its per-shape table's
// row; tile_m/n/k are that layout's tile; undefined in a pinned kernel: the tuning's linear_coopmat).
// choose_linear_kernel takes the family and tiles from device_tuning(caps).
struct LinearKernel {
  int rows = 8, cols = 3, lanes = 0, sg_m = 2;
  bool vectorized = true;
  KernelFamily family = KernelFamily::texel;
  int tile_m = 64, tile_n = 64, tile_k = 16;
  CoopmatTile coopmat;
};
LinearKernel choose_linear_kernel(const vk::Context& ctx, const LinearShape& shape, DType w_dtype);
// The dtype a model keeps its bf16-stored GEMM weights in on this device: f16 where the linear family is coopmat
// (the tensor cores' operand type; DeviceTuning::linear_weights_fp16), else bf16, as stored.
DType gemm_weight_dtype(const vk::DeviceCaps& caps);
// The dtype a producer writes a GEMM's X in on this device: f16 where the linear family is coopmat (the tensor
// cores' operand type; DeviceTuning::linear_activations_fp16), else f32. linear() reads f16 X on the tiled and
// coopmat families (the ones a coopmat tuning can fall back to).
DType gemm_activation_dtype(const vk::DeviceCaps& caps);
void linear_batched_with(vk::Recorder& rec, const Tensor& x, const Tensor& w, const Tensor& y,
                         const LinearShape& shape, const LinearEpilogue& ep, LinearKernel kernel);

}  // namespace dvs::ops
