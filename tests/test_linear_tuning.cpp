// Which linear kernel family and tensor-core layout the tuning table picks, on faked device property lists (no
// device needed): the GPUs' layout (8 subgroups of 32 over 128x128x32 at 16x16x16) where it fits, a smaller one
// where shared memory is short, the lavapipe-sized one at 8 lanes and 8x8x8; tiled without a tensor-core shape;
// CPU drivers keep the texel kernel.
#include <gtest/gtest.h>

#include "tensor/coopmat_layout.hpp"
#include "tensor/kernel_tuning.hpp"

namespace dvs {
namespace {

vk::DeviceCaps gpu(uint32_t subgroup, uint32_t shared, bool coopmat, uint32_t side = 16) {
  vk::DeviceCaps c;
  c.name = "faked GPU";
  c.type = VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU;
  c.subgroup_size = subgroup;
  c.subgroup_shuffle = true;
  c.max_compute_shared_memory = shared;
  c.max_workgroup_invocations = 1024;
  c.cooperative_matrix = coopmat;
  if (coopmat) {
    vk::CooperativeMatrixShape s;
    s.m = s.n = s.k = side;
    c.cooperative_matrix_shapes.push_back(s);
  }
  return c;
}

// Debian trixie-backports' Mesa 26.1 lavapipe: 8 lanes (size control 8..8, 32 subgroups per workgroup),
// 32 KiB of shared memory, fp16 x fp16 + fp32 listed at 8x8x8 only.
vk::DeviceCaps lavapipe_26() {
  vk::DeviceCaps c = gpu(8, 32 * 1024, true, 8);
  c.name = "faked llvmpipe 26.1";
  c.type = VK_PHYSICAL_DEVICE_TYPE_CPU;
  c.subgroup_size_control = c.compute_required_subgroup_size = true;
  c.min_subgroup_size = c.max_subgroup_size = 8;
  c.max_compute_workgroup_subgroups = 32;
  return c;
}

bool same(const ops::CoopmatTile& a, const ops::CoopmatTile& b) {
  return a.sg_m == b.sg_m && a.sg_n == b.sg_n && a.frags_m == b.frags_m && a.frags_n == b.frags_n && a.k == b.k;
}

TEST(LinearTuning, CoopmatOnSubgroup32With48KiB) {
  ops::DeviceTuning t = ops::select_tuning(gpu(32, 48 * 1024, true), "");
  EXPECT_EQ(t.entry, "gpu-coopmat");
  EXPECT_EQ(t.linear, ops::KernelFamily::coopmat);
  EXPECT_EQ(t.coopmat.k, 16u);
  // The H200's best (2026-11-29): 2 x 2 subgroups of 32 lanes, 4 x 4 fragments each (64 x 64 per subgroup), K 32:
  // 128 x 128 x 32, 44 KiB.
  EXPECT_EQ(t.coopmat_lanes, 32);
  EXPECT_TRUE(same(t.linear_coopmat, {2, 2, 4, 4, 32}));
  const ops::CoopmatGemm g = ops::linear_coopmat_layout(t);
  EXPECT_EQ(g.tile_m(), 128);
  EXPECT_EQ(g.tile_n(), 128);
  EXPECT_EQ(g.invocations(), 128u);
  EXPECT_EQ(ops::linear_coopmat_shared_bytes(g), 44u * 1024);
  // The tiled family keeps its own tile.
  EXPECT_EQ(t.linear_tile_m, 64);
  EXPECT_EQ(t.linear_tile_k, 16);
}

TEST(LinearTuning, SmallerLayoutWhereSharedMemoryIsShort) {
  // 32 KiB: the second row, 2 x 2 subgroups of 2 x 2 fragments (64 x 64 x 32, 24 KiB).
  ops::DeviceTuning t = ops::select_tuning(gpu(32, 32 * 1024, true), "");
  EXPECT_EQ(t.linear, ops::KernelFamily::coopmat);
  EXPECT_TRUE(same(t.linear_coopmat, {2, 2, 2, 2, 32}));
  EXPECT_EQ(ops::linear_coopmat_shared_bytes(ops::linear_coopmat_layout(t)), 24u * 1024);
  // 64 lanes: the first row, at 256 invocations.
  ops::DeviceTuning w = ops::select_tuning(gpu(64, 64 * 1024, true), "");
  EXPECT_EQ(w.linear, ops::KernelFamily::coopmat);
  EXPECT_EQ(w.coopmat_lanes, 64);
  EXPECT_TRUE(same(w.linear_coopmat, {2, 2, 4, 4, 32}));
  EXPECT_EQ(ops::linear_coopmat_layout(w).invocations(), 256u);
  // Not even the smallest row (16 KiB): tiled, and why.
  ops::DeviceTuning s = ops::select_tuning(gpu(32, 8 * 1024, true), "");
  EXPECT_EQ(s.linear, ops::KernelFamily::tiled);
  EXPECT_NE(s.linear_unfit.find("shared memory"), std::string::npos) << s.linear_unfit;
  EXPECT_NE(ops::describe_tuning(s).find("coopmat does not fit"), std::string::npos) << ops::describe_tuning(s);
}

TEST(LinearTuning, TiledWithoutATensorCoreShape) {
  ops::DeviceTuning t = ops::select_tuning(gpu(32, 48 * 1024, false), "");
  EXPECT_EQ(t.linear, ops::KernelFamily::tiled);
  EXPECT_EQ(t.linear_tile_m, 64);
  EXPECT_EQ(t.linear_tile_k, 16);
  EXPECT_EQ(t.linear_unfit, "");  // the gpu entry asked for tiled
  // Forcing coopmat on a device without a shape gives tiled, and says why.
  ops::DeviceTuning f = ops::select_tuning(gpu(32, 48 * 1024, false), "linear=coopmat");
  EXPECT_EQ(f.linear, ops::KernelFamily::tiled);
  EXPECT_NE(f.linear_unfit.find("no fp16 x fp16 + fp32 cooperative-matrix shape"), std::string::npos) << f.linear_unfit;
  // coopmat=off asks for tiled: no fallback.
  EXPECT_EQ(ops::select_tuning(gpu(32, 48 * 1024, true), "coopmat=off").linear_unfit, "");
}

TEST(LinearTuning, LavapipeSizedLayouts) {
  // The coopmat entry forced on lavapipe 26.1: its listed 8x8x8, 8 lanes, the GPUs' arrangement of subgroups and
  // fragments (64 x 64 x 32, 32 invocations, 21 KiB).
  ops::DeviceTuning t = ops::select_tuning(lavapipe_26(), "gpu-coopmat");
  EXPECT_EQ(t.linear, ops::KernelFamily::coopmat);
  EXPECT_EQ(t.conv, ops::KernelFamily::coopmat);
  EXPECT_EQ(t.attention, ops::KernelFamily::coopmat);
  EXPECT_EQ(t.coopmat.m, 8u);
  EXPECT_EQ(t.coopmat.k, 8u);
  EXPECT_EQ(t.coopmat_lanes, 8);
  EXPECT_TRUE(same(t.linear_coopmat, {2, 2, 4, 4, 32}));
  EXPECT_EQ(ops::linear_coopmat_layout(t).tile_m(), 64);
  EXPECT_EQ(ops::linear_coopmat_layout(t).invocations(), 32u);
  EXPECT_EQ(ops::linear_coopmat_shared_bytes(ops::linear_coopmat_layout(t)), 21u * 1024);
  EXPECT_TRUE(same(t.conv_coopmat, {4, 2, 2, 4, 32}));
  EXPECT_EQ(t.attention_coopmat_subgroups, 4);
  // The GPUs' 16x16x16 forced: linear takes the 64 x 64 row (the first two need 44 and 48 KiB), attention 2 subgroups
  // (4 need 44 KiB at 64 keys), conv keeps 128 x 128 (28 KiB) with 64 invocations gathering 2 pixels each.
  ops::DeviceTuning f = ops::select_tuning(lavapipe_26(), "gpu-coopmat,coopmat=16x16x16");
  EXPECT_EQ(f.coopmat.m, 16u);
  EXPECT_TRUE(same(f.linear_coopmat, {2, 2, 2, 2, 32}));
  EXPECT_TRUE(same(f.conv_coopmat, {4, 2, 2, 4, 32}));
  EXPECT_EQ(f.attention_coopmat_subgroups, 2);
  // 2 x 16 rows: K, V [64][72] halves, scores [32][68] floats, P [32][72] halves.
  EXPECT_EQ(ops::attention_coopmat_shared_bytes(ops::attention_coopmat_layout(f), 64),
            2u * 64 * 72 * 2 + 32 * 68 * 4 + 32 * 72 * 2);
  // The default entry is untouched: texel kernels.
  EXPECT_EQ(ops::select_tuning(lavapipe_26(), "").linear, ops::KernelFamily::texel);
}

TEST(LinearTuning, CpuKeepsTexel) {
  vk::DeviceCaps c = gpu(8, 32 * 1024, false);
  c.type = VK_PHYSICAL_DEVICE_TYPE_CPU;
  EXPECT_EQ(ops::select_tuning(c, "").linear, ops::KernelFamily::texel);
  EXPECT_EQ(ops::select_tuning(c, "linear=tiled").linear, ops::KernelFamily::tiled);
}

}  // namespace
}  // namespace dvs
