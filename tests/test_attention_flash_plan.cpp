// Which attention kernel family runs a call (ops_attention_flash.cpp's plan), from faked device properties:
// nothing is allocated or dispatched, so the coopmat choice is checked here although lavapipe has no tensor
// cores (the coopmat kernel itself runs only on a device that has them).
#include <gtest/gtest.h>

#include <cstdlib>

#include "tensor/coopmat_layout.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_attention.hpp"
#include "tensor/ops_attention_flash.hpp"

namespace dvs::test {
namespace {

using ops::AttentionShape;
using ops::KernelFamily;

// An H100-like device: 48 KiB of shared memory, subgroups of 32, an fp16 16x16x16 tensor-core shape.
vk::DeviceCaps gpu_caps(uint32_t subgroup, bool coopmat) {
  vk::DeviceCaps caps;
  caps.name = "fake GPU, subgroup " + std::to_string(subgroup) + (coopmat ? ", coopmat" : "");
  caps.type = VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU;
  caps.subgroup_size = subgroup;
  caps.subgroup_shuffle = caps.float16_arithmetic = caps.vulkan_memory_model = true;
  caps.max_storage_buffer_range = 0xffffffffull;
  caps.max_texel_buffer_elements = 1ull << 27;
  caps.max_memory_allocation_size = 64ull << 30;
  caps.min_storage_buffer_offset_alignment = caps.min_texel_buffer_offset_alignment = 16;
  caps.max_compute_shared_memory = 48 << 10;
  caps.max_workgroup_invocations = 1024;
  caps.max_workgroup_count[0] = 0x7fffffff;
  caps.max_workgroup_count[1] = caps.max_workgroup_count[2] = 65535;
  if (coopmat) {
    caps.cooperative_matrix = true;
    vk::CooperativeMatrixShape s;
    s.m = s.n = s.k = 16;
    caps.cooperative_matrix_shapes.push_back(s);
  }
  return caps;
}

TEST(AttentionFlashPlan, TuningPicksTheFamily) {
  if (std::getenv("DVS_TUNING")) GTEST_SKIP() << "checks the table's own choices, which DVS_TUNING overrides";
  EXPECT_EQ(ops::select_tuning(gpu_caps(32, true), "").attention, KernelFamily::coopmat);
  // 64 lanes: the same layout at 4 lanes per row (the kernels take their lanes from the tuning).
  const ops::DeviceTuning w = ops::select_tuning(gpu_caps(64, true), "");
  EXPECT_EQ(w.attention, KernelFamily::coopmat);
  EXPECT_EQ(w.coopmat_lanes, 64);
  EXPECT_EQ(ops::select_tuning(gpu_caps(32, false), "").attention, KernelFamily::tiled);
  EXPECT_EQ(ops::select_tuning(gpu_caps(32, true), "coopmat=off").attention, KernelFamily::tiled);
  EXPECT_FALSE(ops::select_tuning(gpu_caps(32, true), "").attention_kv_workspace);
  EXPECT_FALSE(ops::attention_workspace_helps(gpu_caps(32, true), {2, 48, 64, 2048, 2048}));
  vk::DeviceCaps cpu = gpu_caps(8, false);
  cpu.type = VK_PHYSICAL_DEVICE_TYPE_CPU;
  EXPECT_EQ(ops::select_tuning(cpu, "").attention, KernelFamily::texel);
  EXPECT_TRUE(ops::attention_workspace_helps(cpu, {2, 48, 64, 2048, 2048}));
}

TEST(AttentionFlashPlan, CogVideoXRealSizeOnTensorCores) {
  if (std::getenv("DVS_TUNING")) GTEST_SKIP() << "checks the table's own choices, which DVS_TUNING overrides";
  const vk::DeviceCaps caps = gpu_caps(32, true);
  // The H200's layout: 4 subgroups of 32 lanes, 16 query rows each, 64-key tiles: 44 KiB at head_dim 64 (rows
  // padded by 16 bytes).
  const ops::CoopmatAttention a = ops::attention_coopmat_layout(ops::select_tuning(caps, ""));
  EXPECT_EQ(a.rows(), 64);
  EXPECT_EQ(a.invocations(), 128u);
  EXPECT_EQ(ops::attention_coopmat_shared_bytes(a, 64), 44u * 1024);
  // 49x480x720: fused QKV [2, 17776, 9216] (1.31 GB) in one storage binding, one dispatch.
  const ops::AttentionSplit p = ops::attention_split_plan_fused(caps, {2, 48, 64, 17776, 17776});
  EXPECT_EQ(p.family, KernelFamily::coopmat);
  EXPECT_TRUE(p.whole);
  // head_dim not a multiple of 16, or above the 64-key tile: the tiled kernel.
  EXPECT_EQ(ops::attention_split_plan_fused(caps, {2, 3, 40, 37, 37}).family, KernelFamily::tiled);
  EXPECT_EQ(ops::attention_split_plan_fused(caps, {2, 3, 72, 37, 37}).family, KernelFamily::tiled);
  EXPECT_EQ(ops::attention_split_plan_fused(caps, {2, 3, 128, 37, 37}).family, KernelFamily::tiled);
  EXPECT_EQ(ops::attention_split_plan_fused(caps, {2, 3, 38, 37, 37}).family, KernelFamily::tiled);  // padded to 40
  // T5 (bias and key mask): the texel kernel.
  EXPECT_EQ(ops::attention_split_plan_fused(caps, {2, 64, 64, 226, 226}, true, true).family, KernelFamily::texel);
}

// Where the device has VK_NV_cooperative_matrix2's row operations, the coopmat2 variant runs and takes 16
// subgroups (256 query rows, 38 KiB at head_dim 64: the H200's best, 2026-11-29); with attention_coopmat2=off the
// KHR kernel keeps 4.
TEST(AttentionFlashPlan, Coopmat2TakesTwoHundredFiftySixRows) {
  if (std::getenv("DVS_TUNING")) GTEST_SKIP() << "checks the table's own choices, which DVS_TUNING overrides";
  vk::DeviceCaps caps = gpu_caps(32, true);
  caps.cooperative_matrix2_row_ops = true;
  const ops::DeviceTuning t = ops::select_tuning(caps, "");
  EXPECT_EQ(ops::attention_coopmat_kernel(caps, t), ops::AttentionKernel::coopmat2);
  EXPECT_EQ(ops::attention_coopmat_layout(t).rows(), 256);
  EXPECT_EQ(ops::attention_coopmat_shared_bytes(ops::attention_coopmat_layout(t), 64, ops::AttentionKernel::coopmat2),
            38u * 1024);
  const ops::DeviceTuning off = ops::select_tuning(caps, "attention_coopmat2=off");
  EXPECT_EQ(ops::attention_coopmat_kernel(caps, off), ops::AttentionKernel::khr);
  EXPECT_EQ(ops::attention_coopmat_layout(off).rows(), 64);
  caps.cooperative_matrix2_row_ops = false;
  EXPECT_EQ(ops::attention_coopmat_kernel(caps, ops::select_tuning(caps, "")), ops::AttentionKernel::khr);
}

TEST(AttentionFlashPlan, CallsOverOneBindingFallBackToTheTexelSplits) {
  vk::DeviceCaps caps = gpu_caps(32, true);
  caps.name += ", 128 MiB bindings";
  caps.max_storage_buffer_range = 128ull << 20;
  const ops::AttentionSplit p = ops::attention_split_plan_fused(caps, {2, 48, 64, 17776, 17776});
  EXPECT_EQ(p.family, KernelFamily::texel);
  EXPECT_FALSE(p.whole);
  // The tiled kernel's key tile shrinks with head_dim to fit shared memory (2·BK·D·4 bytes).
  vk::DeviceCaps small = gpu_caps(32, false);
  small.name += ", 32 KiB shared";
  small.max_compute_shared_memory = 32 << 10;
  EXPECT_EQ(ops::attention_split_plan_fused(small, {1, 1, 256, 5, 5}).family, KernelFamily::tiled);
}

}  // namespace
}  // namespace dvs::test
