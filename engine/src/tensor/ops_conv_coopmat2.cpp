#include "tensor/ops_conv_coopmat2.hpp"

#include <array>

#include "tensor/coopmat_layout.hpp"
#include "tensor/kernel_tuning.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"

namespace dvs::ops {

uint32_t ConvCoopmat2::groups_x(int64_t nfo, int64_t nr, int64_t nc) const {
  const int64_t g = nfo * ((nr + rows - 1) / rows) * ((nc + cols - 1) / cols);
  return g <= int64_t(max_groups_x) ? uint32_t(g) : 0u;
}

bool ConvCoopmat2::takes(std::initializer_list<uint64_t> byte_offsets, int64_t ys_f, int64_t nfo, int64_t nr,
                         int64_t nc) const {
  if (!pipe || (nfo > 1 && ys_f % 4 != 0) || groups_x(nfo, nr, nc) == 0) return false;
  for (uint64_t o : byte_offsets)
    if (o % 16 != 0) return false;
  return true;
}

std::string conv_coopmat2_refusal(const vk::DeviceCaps& caps, const DeviceTuning& tune, const ConvCall& c) {
  const DeviceTuning::ConvCoopmat2Tile& t = tune.conv_coopmat2_tile;
  if (!tune.conv_coopmat2) return "off (conv_coopmat2)";
  if (!c.coopmat) return "the conv family is not the tensor-core kernel";
  if (!c.x_f16) return "the input is repacked f32 (conv_activations_fp16)";
  if (c.weight_code != 1) return "the weights are not fp16 (conv_weights_fp16)";
  if (c.stride != 1) return "stride " + std::to_string(c.stride);
  if (c.cp % t.k != 0) return std::to_string(c.cp) + " packed input channels, not a multiple of the tile's K";
  // y as [channels][rows][columns] per frame: columns innermost and each dimension nesting in the next (the tensor
  // layout's strides must).
  if (c.ys_w != 1 || c.ys_h < c.wo || c.ys_c < c.ys_h * c.ho) return "y is not channels-first";
  return linear_coopmat2_unfit(caps, {t.rows * t.cols, t.n, t.k, t.invocations});
}

ConvCoopmat2 conv_coopmat2_kernel(vk::Context& ctx, const ConvCall& c) {
  const vk::DeviceCaps& caps = ctx.caps();
  const DeviceTuning& tune = device_tuning(caps);
  const DeviceTuning::ConvCoopmat2Tile& t = tune.conv_coopmat2_tile;
  ConvCoopmat2 k;
  if (!conv_coopmat2_refusal(caps, tune, c).empty()) return k;
  const std::array<uint32_t, 6> spec = {uint32_t(t.invocations), uint32_t(t.rows), uint32_t(t.cols), uint32_t(t.n),
                                        uint32_t(t.k), c.bias_code};
  k.pipe = &ctx.pipelines().get("nn/conv_coopmat2", spec);
  k.rows = t.rows, k.cols = t.cols, k.n = t.n;
  k.max_groups_x = caps.max_workgroup_count[0];
  return k;
}

}  // namespace dvs::ops
