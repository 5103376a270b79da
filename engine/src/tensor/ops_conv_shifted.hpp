// A convolution as the tensor-core GEMM itself (DeviceTuning::conv_shifted_gemm; shaders/linalg/conv_shifted_io.glsl
// says how): for a stride-1 "same" convolution (every causal 3D conv of the VAE, its 3x3 and 1x1 convs, the 3x3 conv
// of upsample2x_conv3x3) with weights packed at load, each chunk of output frames (or of one frame's rows) repacks its
// input fp16 channels-last on the zero-padded grid (of the upsampled input where the call upsamples), and
// nn/conv_shifted_coopmat (linear_coopmat.comp's tile, 16-byte loads and order) multiplies it by the packed weights,
// each K step's rows shifted by its tap's offset on the grid; the epilogue drops the grid's padding rows and adds the
// bias. No gather: the loads are a GEMM's. ops_conv.cpp tries it first and runs the implicit-GEMM kernels where it
// refuses.
#pragma once
#include <cstdint>
#include <string>

#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv.hpp"
#include "tensor/ops_conv_job.hpp"
#include "vk/recorder.hpp"

namespace dvs::ops::conv {

// What record_conv knows of the call besides the job: the family runs the tensor-core kernel (not its twin), the
// input repack is fp16, the repack's pixels per invocation, the staging budget for one chunk's repacked input, and
// the caller's staging (ConvScratch; nullptr: recorder scratch).
struct ShiftedCall {
  bool coopmat = false, x_f16 = false;
  int64_t pack_columns = 0;
  uint64_t input_bytes = 0;
  const ConvScratch* given = nullptr;
};

// Why the call does not take the shifted GEMM on a device with these caps and tuning ("" when it does): the switch,
// the family, the stride and padding, the weights, the channels, the layout, or chunks that do not fit.
std::string shifted_refusal(const vk::DeviceCaps& caps, const DeviceTuning& tune, const ConvJob& j,
                            const ConvWeights& w, const ShiftedCall& call);

// Records the convolution through the shifted GEMM and returns true, or returns false (nothing recorded) where
// shifted_refusal says why not.
bool record_shifted(vk::Recorder& rec, const char* op, const ConvJob& j, const Tensor& x, const ConvWeights& w,
                    const Tensor* bias, const Tensor& y, const ShiftedCall& call);

}  // namespace dvs::ops::conv
