// The convolution kernel through VK_NV_cooperative_matrix2 (shaders/nn/conv_coopmat2.comp, DeviceTuning::
// conv_coopmat2): whether a call takes it, its pipeline and its grid. ops_conv.cpp dispatches it in place of the KHR
// kernel (conv_coopmat.comp) for the chunks it takes, over the same operands and push constants.
#pragma once
#include <cstdint>
#include <initializer_list>
#include <string>

#include "tensor/kernel_tuning.hpp"

namespace dvs::vk {
class Context;
struct DeviceCaps;
struct Pipeline;
}  // namespace dvs::vk

namespace dvs::ops {

// What a call's chunks need to know about the kernel; `pipe` nullptr: the call does not take it.
struct ConvCoopmat2 {
  const vk::Pipeline* pipe = nullptr;
  int64_t rows = 0, cols = 0, n = 0;  // a workgroup's output patch and channels
  uint32_t max_groups_x = 0;
  // Workgroups along x for a chunk of nfo frames x nr rows x nc columns (0: more than the device allows).
  uint32_t groups_x(int64_t nfo, int64_t nr, int64_t nc) const;
  // Whether a chunk takes it: its packed input's and weights' bindings and its y's first element (byte offsets in
  // their buffers), and with y's frame stride ys_f each frame's first element, 16-byte aligned (tensor loads and
  // stores need their bases so), and its grid within the device's.
  bool takes(std::initializer_list<uint64_t> byte_offsets, int64_t ys_f, int64_t nfo, int64_t nr, int64_t nc) const;
};

// The call's description as the kernel's conditions read it: packed input channels cp (of one input-channel chunk),
// the weights' and bias's codes (0 f32, 1 f16, 2 bf16), an fp16 repack, the stride, y's strides and the output's rows
// and columns; coopmat: the conv family runs the tensor-core kernel (not its twin).
struct ConvCall {
  bool coopmat = false, x_f16 = false;
  int64_t cp = 0, stride = 1, ho = 0, wo = 0, ys_c = 0, ys_h = 0, ys_w = 0;
  uint32_t weight_code = 0, bias_code = 0;
};
// Why a call does not take the kernel on a device with these caps and tuning ("" when it does).
std::string conv_coopmat2_refusal(const vk::DeviceCaps& caps, const DeviceTuning& tune, const ConvCall& call);
ConvCoopmat2 conv_coopmat2_kernel(vk::Context& ctx, const ConvCall& call);

}  // namespace dvs::ops
