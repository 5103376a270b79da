// What the tensor-core kernels (linalg/linear_coopmat, nn/conv_coopmat, nn/attention_flash_coopmat) and their
// fp32 twins need of a device for one layout: the specialization constants that lay them out, shared memory,
// invocations, subgroups, and the index maps' divisibility rules. The tuning table (kernel_tuning.cpp) picks
// layouts for which *_unfit() is ""; the ops create pipelines through coopmat_pipeline(), which refuses a
// layout the device cannot hold with a dvs::Error naming the limit and the DVS_TUNING field to change, and
// requires the subgroup size the layout is written for. The kernels' own comments say what each constant does.
#pragma once
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "tensor/kernel_tuning.hpp"

namespace dvs::vk {
class Context;
struct Pipeline;
}  // namespace dvs::vk

namespace dvs::ops {

// A GEMM-shaped kernel's layout: fragment, lanes per subgroup, workgroup tile.
struct CoopmatGemm {
  CoopmatShape frag;
  int lanes = 0;
  CoopmatTile tile;
  int64_t tile_m() const { return int64_t(tile.sg_m) * tile.frags_m * frag.m; }  // rows (linear) / pixels (conv)
  int64_t tile_n() const { return int64_t(tile.sg_n) * tile.frags_n * frag.n; }  // columns / output channels
  uint32_t invocations() const { return uint32_t(tile.subgroups() * lanes); }
  std::string describe() const;  // "128x128x32 (2x4 subgroups of 32 lanes, 4x2 fragments of 16x16x16 each)"
};

// The flash-attention kernel's layout: `subgroups` of frag.m query rows each, `block_k` keys per tile.
struct CoopmatAttention {
  CoopmatShape frag;
  int lanes = 0, subgroups = 0, block_k = 0;
  int64_t rows() const { return int64_t(subgroups) * frag.m; }  // query rows per workgroup
  uint32_t invocations() const { return uint32_t(subgroups * lanes); }
  std::string describe() const;
};

// The layouts the tuning holds for this device (coopmat_lanes and the per-kernel fields of DeviceTuning). The
// fragment is the device's shape; on a device without one (where only the twins run) the GPUs' 16x16x16.
CoopmatGemm linear_coopmat_layout(const DeviceTuning& t);
// The layout of a GEMM of m rows (per batch item) by n columns: its row of the per-shape table
// (DeviceTuning::linear_coopmat_by_shape), else the one above.
CoopmatGemm linear_coopmat_layout(const DeviceTuning& t, int64_t m, int64_t n);
CoopmatGemm conv_coopmat_layout(const DeviceTuning& t);
CoopmatAttention attention_coopmat_layout(const DeviceTuning& t);

// Which attention kernel of the family runs: nn/attention_flash_coopmat (KHR), its coopmat2 variant, or the
// fp32 twin (tests on devices without tensor cores).
enum class AttentionKernel { khr, coopmat2, twin };
// The tensor-core kernel this device runs under this tuning: coopmat2 where attention_coopmat2 is on, the device
// has VK_NV_cooperative_matrix2's row operations and the fragment's N equals its K; else khr.
AttentionKernel attention_coopmat_kernel(const vk::DeviceCaps& caps, const DeviceTuning& t);

// Shared memory in bytes. Linear: two stages of fp16 X and W tiles (rows padded by 8 halves) and one fp32
// fragment of staging per subgroup. Conv: one stage of the same and the staging. Attention at head_dim D
// (D <= block_k): K and V tiles (fp16) and per subgroup: (KHR) the scores / P·V tile (fp32) and P (fp16);
// (coopmat2) one fp32 fragment of Q / O staging; (twin) the KHR kernel's, its own copy of Q and the lanes'
// exchange slots.
uint64_t linear_coopmat_shared_bytes(const CoopmatGemm& g);
uint64_t conv_coopmat_shared_bytes(const CoopmatGemm& g, int stages = 1);
// The conv kernel's operand stages: 2 (the next step's gather during this step's products) where asked for
// (DeviceTuning::conv_coopmat_double_buffer) and they fit the device's shared memory, else 1, which the layout
// checks (conv_coopmat_unfit) require to fit.
int conv_coopmat_stages(const vk::DeviceCaps& caps, const CoopmatGemm& g, bool double_buffer);
uint64_t attention_coopmat_shared_bytes(const CoopmatAttention& a, int64_t head_dim,
                                        AttentionKernel kernel = AttentionKernel::khr);

// Why the device cannot run the layout ("" when it can). `twin`: the fp32 twin (no tensor cores, lanes emulated
// by the workgroup), which needs the index maps and the memory but neither the subgroup size nor the shape.
std::string linear_coopmat_unfit(const vk::DeviceCaps& caps, const CoopmatGemm& g);
std::string conv_coopmat_unfit(const vk::DeviceCaps& caps, const CoopmatGemm& g, bool twin);
// head_dim 0: the largest the kernel takes (block_k), what the tuning checks.
std::string attention_coopmat_unfit(const vk::DeviceCaps& caps, const CoopmatAttention& a, int64_t head_dim,
                                    AttentionKernel kernel);
// Why the kernel does not take head_dim at all, on any device ("" when it does).
std::string attention_coopmat_head_dim_unfit(const CoopmatAttention& a, int64_t head_dim);

// Specialization constants (the kernels' constant_id order).
// linear: vector_loads selects the 16-byte load path (the host checked K, strides and offsets), group_m the
// workgroup order's band of tile rows (DeviceTuning::linear_coopmat_group_m), ablation a measurement variant
// (DeviceTuning::linear_coopmat_ablation: 0 none), x_code X's storage (0 f32, 1 f16), y_f16 Y stored f16.
std::vector<uint32_t> linear_coopmat_spec(const CoopmatGemm& g, uint32_t weight_code, bool vector_loads,
                                          uint32_t group_m, uint32_t ablation = 0, uint32_t x_code = 0,
                                          bool y_f16 = false);
// conv: x_f16 the repacked input in fp16, bias_code the bias's storage (UINT32_MAX: the weights'), vec8 the
// 16-byte gathers (conv_coopmat.comp's VEC8; the caller checks conv_coopmat_vec8_fits).
std::vector<uint32_t> conv_coopmat_spec(const CoopmatGemm& g, uint32_t weight_code, int stages, bool x_f16 = false,
                                        uint32_t bias_code = UINT32_MAX, bool vec8 = false);
// Why the coopmat2 GEMM (linalg/linear_coopmat2.comp) cannot run tile `t` on this device ("" when it can): the
// device needs VK_NV_cooperative_matrix2's workgroup scope, flexible dimensions, tensor addressing and per-element
// operations, and a workgroup-scope fp16 x fp16 + fp32 shape for t.invocations whose granularity divides the tile.
std::string linear_coopmat2_unfit(const vk::DeviceCaps& caps, const DeviceTuning::Coopmat2Tile& t);

// Whether conv_coopmat.comp's 16-byte gathers (VEC8) take a convolution of `cp` packed input channels (a chunk's,
// rounded up to 8), weights of `weight_code` (0 f32, 1 f16, 2 bf16) and kh x kw taps per frame: an fp16 input
// repack, channels a multiple of the tile's K, 16-bit weights, kh and kw at most 16 (the shader's tap masks), and a
// tile whose pixels and channels are whole passes of the gather (invocations / (K / 8) rows each).
bool conv_coopmat_vec8_fits(const CoopmatGemm& g, int64_t cp, uint32_t weight_code, int64_t kh, int64_t kw, bool x_f16);
// The specialization constants of the tensor-core attention kernels (attention_flash_coopmat_decl.glsl) and the
// twin: the layout, head_dim, and which operands are fp16.
std::vector<uint32_t> attention_coopmat_spec(const CoopmatAttention& a, int64_t head_dim, bool out_f16 = false,
                                             bool kv_f16 = false, bool q_f16 = false);

// The pipeline of a tensor-core kernel: throws dvs::Error("<shader>: <unfit>") when `unfit` is not empty, else
// creates it with subgroups of `lanes` required (twins: lanes 0, nothing required).
const vk::Pipeline& coopmat_pipeline(vk::Context& ctx, const std::string& shader, std::span<const uint32_t> spec,
                                     uint32_t lanes, const std::string& unfit);

}  // namespace dvs::ops
