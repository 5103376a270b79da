// Which linear kernel family the tuning table picks, on faked device property lists (no device needed):
// tensor cores only with a 16x16 fp16 shape, subgroups of 32 and 48 KiB of shared memory (the coopmat
// kernel's layout); else the tiled kernel; CPU drivers keep the texel kernel.
#include <gtest/gtest.h>

#include "tensor/kernel_tuning.hpp"

namespace dvs {
namespace {

vk::DeviceCaps gpu(uint32_t subgroup, uint32_t shared, bool coopmat) {
  vk::DeviceCaps c;
  c.type = VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU;
  c.subgroup_size = subgroup;
  c.subgroup_shuffle = true;
  c.max_compute_shared_memory = shared;
  c.cooperative_matrix = coopmat;
  if (coopmat) {
    vk::CooperativeMatrixShape s;
    s.m = s.n = s.k = 16;
    c.cooperative_matrix_shapes.push_back(s);
  }
  return c;
}

TEST(LinearTuning, CoopmatOnSubgroup32With48KiB) {
  ops::DeviceTuning t = ops::select_tuning(gpu(32, 48 * 1024, true), "");
  EXPECT_EQ(t.entry, "gpu-coopmat");
  EXPECT_EQ(t.linear, ops::KernelFamily::coopmat);
  EXPECT_EQ(t.linear_tile_m, 128);
  EXPECT_EQ(t.linear_tile_n, 128);
  EXPECT_EQ(t.linear_tile_k, 32);
  EXPECT_EQ(t.coopmat.k, 16u);
}

TEST(LinearTuning, TiledWhereTheCoopmatLayoutDoesNotFit) {
  for (const vk::DeviceCaps& c : {gpu(64, 64 * 1024, true), gpu(32, 32 * 1024, true), gpu(32, 48 * 1024, false)}) {
    ops::DeviceTuning t = ops::select_tuning(c, "");
    EXPECT_EQ(t.linear, ops::KernelFamily::tiled);
    EXPECT_EQ(t.linear_tile_m, 64);
    EXPECT_EQ(t.linear_tile_k, 16);
  }
  // Forcing coopmat on a device without a shape gives tiled.
  EXPECT_EQ(ops::select_tuning(gpu(32, 48 * 1024, false), "linear=coopmat").linear, ops::KernelFamily::tiled);
}

TEST(LinearTuning, CpuKeepsTexel) {
  vk::DeviceCaps c = gpu(8, 32 * 1024, false);
  c.type = VK_PHYSICAL_DEVICE_TYPE_CPU;
  EXPECT_EQ(ops::select_tuning(c, "").linear, ops::KernelFamily::texel);
  EXPECT_EQ(ops::select_tuning(c, "linear=tiled").linear, ops::KernelFamily::tiled);
}

}  // namespace
}  // namespace dvs
