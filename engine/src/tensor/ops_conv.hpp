// Convolutions and resampling of the CogVideoX 3D VAE and of the transformer's patch embedding.
// Video tensors are [B, C, F, H, W] (contiguous, f32). Weights are [Cout, Cin, kt, kh, kw] (3D) or
// [Cout, Cin, kh, kw] (2D), stored f32, f16 or bf16 and widened in the shader, or packed once at load
// (ops_conv_weights.hpp); the bias (optional, [Cout]) is f32, f16 or bf16, any of them whatever the weights' dtype.
// Arithmetic and accumulation are fp32. Every function records into `rec`;
// outputs are allocated by the caller with the shapes the *_shape() helpers give, and must not alias
// the inputs. The convolutions run as an implicit GEMM (shaders/nn/conv_gemm.comp) over chunks of output
// frames and rows whose input is first repacked channels-last into recorder scratch (the chunks stay within
// maxStorageBufferRange and maxTexelBufferElements); stored weights are repacked once per call, packed ones
// are bound in place (a slice is repacked only where the call splits the input channels). x and a cache
// are read through texel buffers: each must start at an allocation-aligned offset (whole tensors and arena
// views do) and hold at most maxTexelBufferElements (2^27 on lavapipe and NVIDIA); y is bound whole.
// The GEMM itself is one of three kernel families (kernel_tuning.hpp, DeviceTuning::conv): texel
// (conv_gemm.comp, CPU drivers), tiled (conv_tiled.comp: shared-memory tiles over storage buffers, fp32) or
// coopmat (conv_coopmat.comp: tensor cores, fp16 operands, fp32 sums); each serves every op below. On the coopmat
// family a stride-1 same-size convolution can run as the tensor-core GEMM kernel itself instead
// (DeviceTuning::conv_shifted_gemm, ops_conv_shifted.hpp: its input repacked on the zero-padded grid).
// (The resampling ops are implemented in ops_resample.cpp.)
#pragma once
#include <cstdint>

#include "tensor/ops_conv_weights.hpp"
#include "tensor/tensor.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops {

// Conv2d applied to every frame. Zero padding per side; output size (H + top + bottom - kh) / stride + 1.
struct Conv2dParams {
  int stride = 1;
  int pad_top = 0, pad_bottom = 0, pad_left = 0, pad_right = 0;
  // false: y is [B, Cout, F, Ho, Wo] (or [N, Cout, Ho, Wo] for 4-D x).
  // true:  y is [B, F, Ho, Wo, Cout] (or [N, Ho, Wo, Cout]): the token layout of the patch embedding.
  bool channels_last_out = false;

  static Conv2dParams same3x3() { return {1, 1, 1, 1, 1, false}; }            // 3x3, stride 1, pad 1
  static Conv2dParams patch(bool tokens = true) { return {2, 0, 0, 0, 0, tokens}; }  // 2x2 stride 2
  // CogVideoXDownsample3D: F.pad(x, (0, 1, 0, 1)) then Conv2d(k=3, s=2, padding=0).
  static Conv2dParams downsample3x3() { return {2, 0, 1, 0, 1, false}; }
};

// Staging memory of one convolution (the input chunk and the weights, repacked). Without it the op takes
// recorder scratch (vk::Recorder::scratch); callers that plan their memory (the VAE) pass buffers of the
// sizes *_scratch() gives, f32 elements each, which depend on shapes alone (not the device, not the weight
// dtype: the weights part is sized for f32): the input part is the whole repacked input, capped at 128 MiB
// (the smallest maxStorageBufferRange Vulkan allows; larger inputs run in chunks of at most that). Weights packed
// at load leave the weights part unused unless the call repacks a slice of them (split input channels, an
// unaligned group); it also bounds the output-channel groups either way.
struct ConvScratch {
  Tensor input, weights;
};
struct ConvScratchSize {
  int64_t input = 0, weights = 0;
};

// x: [B, Cin, F, H, W] or [N, Cin, H, W] (images); w: [Cout, Cin, kh, kw] or [Cout, Cin, 1, kh, kw].
void conv2d(vk::Recorder& rec, const Tensor& x, const ConvWeights& w, const Tensor* bias, const Tensor& y,
            const Conv2dParams& params, const ConvScratch* scratch = nullptr);
ConvScratchSize conv2d_scratch(const Shape& x, const Shape& w);
Shape conv2d_shape(const Shape& x, const Shape& w, const Conv2dParams& params);

// CogVideoXCausalConv3d (pad_mode "constant"): kernel [Cout, Cin, kt, kh, kw] with odd kh, kw; spatial zero
// padding (kh-1)/2, (kw-1)/2; the time axis is preceded by P = kt-1 frames: `cache_in` [B, Cin, P, H, W]
// when given (the previous frame batch), else P copies of frame 0. y: [B, Cout, F, H, W].
// If `cache_out` is given it receives the next cache: the last P frames of the padded input [prefix ; x]
// (what diffusers returns as conv_cache). cache_out may be the same tensor as cache_in (updated in place
// after the convolution has read it). With kt = 1 this is the pointwise / per-frame conv and caches are
// not allowed.
void causal_conv3d(vk::Recorder& rec, const Tensor& x, const ConvWeights& w, const Tensor* bias, const Tensor& y,
                   const Tensor* cache_in = nullptr, const Tensor* cache_out = nullptr,
                   const ConvScratch* scratch = nullptr);
ConvScratchSize causal_conv3d_scratch(const Shape& x, const Shape& w);  // also conv1x1
Shape causal_conv3d_cache_shape(const Shape& x, const Shape& w);  // [B, Cin, kt-1, H, W]

// 1x1x1 convolution (CogVideoXSafeConv3d k=1, conv_shortcut): x [B, Cin, F, H, W], w [Cout, Cin(,1,1,1)].
void conv1x1(vk::Recorder& rec, const Tensor& x, const ConvWeights& w, const Tensor* bias, const Tensor& y,
             const ConvScratch* scratch = nullptr);

// Temporal pair averaging of CogVideoXDownsample3D (compress_time): odd F keeps frame 0 and averages the
// rest in pairs; even F averages all pairs. y: [B, C, downsample_time_frames(F), H, W].
int64_t downsample_time_frames(int64_t frames);
void avgpool_time_pairs(vk::Recorder& rec, const Tensor& x, const Tensor& y);

// Nearest-neighbour resize of x [B, C, F, H, W] to y's size [B, C, Fo, Ho, Wo] (PyTorch "nearest" index
// rule). keep_first_frame: frame 0 maps alone to output frame 0 and frames 1.. are resized F-1 -> Fo-1
// (CogVideoXUpsample3D with compress_time, CogVideoXSpatialNorm3D's zq resize).
void upsample_nearest(vk::Recorder& rec, const Tensor& x, const Tensor& y, bool keep_first_frame = false);

// CogVideoXUpsample3D's nearest x2 (before its conv): spatial x2 always; with compress_time, frames are
// doubled too except that for odd F > 1 frame 0 stays single; F = 1 stays 1. y: upsample2x_shape(x, ct).
Shape upsample2x_shape(const Shape& x, bool compress_time);
void upsample2x(vk::Recorder& rec, const Tensor& x, const Tensor& y, bool compress_time);

// CogVideoXUpsample3D whole: upsample2x followed by its Conv2d(3x3, stride 1, pad 1) per frame, fused so
// the 4x larger upsampled tensor is never stored. w: [Cout, Cin, 3, 3]. y: [B, Cout, Fo, 2H, 2W] with Fo
// from upsample2x_shape. Results are bit-identical to upsample2x then conv2d(same3x3).
void upsample2x_conv3x3(vk::Recorder& rec, const Tensor& x, const ConvWeights& w, const Tensor* bias, const Tensor& y,
                        bool compress_time, const ConvScratch* scratch = nullptr);
ConvScratchSize upsample2x_conv3x3_scratch(const Shape& x, const Shape& w, bool compress_time);

// Tuning / testing knobs of the convolution kernel (shaders/nn/conv_gemm.comp; defaults come from
// tensor/kernel_tuning.cpp). Register block: `rows` output pixels x 8*`cols` output channels per 8-lane
// cluster (0 = automatic), `lanes` -1 automatic, else GemmTile::lanes (2 = no subgroup shuffles),
// `k_unroll` 8-channel steps per loop trip (0 automatic; 1, 2 or 4). `pack_columns`: pixels of a row per
// invocation of the input repack (shaders/nn/conv_pack_input.comp; 0 automatic).
// `coopmat_twin`: run the coopmat family's tiling, loads and epilogue with its fp32 twin shader
// (nn/conv_coopmat_twin, a variant of shaders/nn/conv_coopmat.comp; no tensor cores) whatever the device's
// family: tests the coopmat kernel's every part but the MMA on devices without cooperative matrices.
struct ConvRegisterBlock {
  int rows = 0, cols = 0, lanes = -1, k_unroll = 0, pack_columns = 0;
  bool coopmat_twin = false;
};
void set_conv_register_block(const ConvRegisterBlock& block);
// Largest repacked input chunk in bytes (0 = the device's limits): smaller values force the frame and row
// splits that the real size needs, on small tensors.
void set_conv_chunk_bytes(uint64_t bytes);
// The dtype a convolution repacks its input chunks in on this device: f16 where the tensor-core kernel (or its twin)
// reads them and DeviceTuning::conv_activations_fp16 is on, else f32 (chunk budgets count its bytes).
DType conv_repack_dtype(const vk::DeviceCaps& caps);

}  // namespace dvs::ops
