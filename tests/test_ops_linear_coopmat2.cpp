// The GEMM through VK_NV_cooperative_matrix2 (linalg/linear_coopmat2.comp, DeviceTuning::linear_coopmat2). Which
// devices and tiles it takes (linear_coopmat2_unfit) against device facts written out here: the H200's, as its
// device run of 2026-11-29 printed them, and variations of them. By value, on a device that has the features (the
// device script runs LinearTest.* there; lavapipe has none of them, so there it skips): f16 X and W, odd sizes,
// unaligned offsets and padded strides (each base offset aligned down, the rest a column shift of the slice), batches
// with their own weights, every epilogue step, the residual in place, and the pipeline that ran. Elsewhere, asking
// for it runs the KHR kernel and the tuning says why.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "support/coopmat2_caps.hpp"
#include "support/linear_test.hpp"
#include "tensor/coopmat_layout.hpp"
#include "vk/shader_registry.hpp"

namespace dvs {
namespace {

using namespace test;

using Tile = ops::DeviceTuning::Coopmat2Tile;

TEST(LinearCoopmat2Fit, TilesTheDeviceShapesTake) {
  const vk::DeviceCaps caps = h200_like();
  EXPECT_EQ(ops::linear_coopmat2_unfit(caps, Tile{}), "");                      // 128x128x32, 256 invocations
  EXPECT_EQ(ops::linear_coopmat2_unfit(caps, Tile{256, 128, 32, 256}), "");
  EXPECT_EQ(ops::linear_coopmat2_unfit(caps, Tile{128, 128, 64, 128}), "");
  EXPECT_EQ(ops::linear_coopmat2_unfit(caps, Tile{64, 64, 16, 32}), "");
  // No fp16 shape at 96 invocations; 80 rows are not whole 32-row granules at 256; 24 not whole 16-K granules.
  EXPECT_NE(ops::linear_coopmat2_unfit(caps, Tile{128, 128, 32, 96}), "");
  EXPECT_NE(ops::linear_coopmat2_unfit(caps, Tile{80, 128, 32, 256}), "");
  EXPECT_NE(ops::linear_coopmat2_unfit(caps, Tile{128, 128, 24, 256}), "");
  // Past the workgroup scope's limits.
  EXPECT_NE(ops::linear_coopmat2_unfit(caps, Tile{2048, 128, 32, 256}), "");
  EXPECT_NE(ops::linear_coopmat2_unfit(caps, Tile{128, 128, 32, 512}), "");
}

TEST(LinearCoopmat2Fit, DevicesWithoutTheFeaturesOrTheTypes) {
  vk::DeviceCaps caps = h200_like();
  caps.cooperative_matrix2_gemm = false;  // e.g. an application's device without workgroup scope enabled
  EXPECT_NE(ops::linear_coopmat2_unfit(caps, Tile{}), "");
  caps = h200_like();
  caps.cooperative_matrix2_facts.reset();
  EXPECT_NE(ops::linear_coopmat2_unfit(caps, Tile{}), "");
  // Only bf16, saturating or f32-result-less shapes: none is the kernel's fp16 x fp16 + fp32.
  caps = h200_like();
  for (vk::CooperativeMatrixFlexibleShape& s : caps.cooperative_matrix2_facts->flexible_shapes)
    s.a = s.b = kBf16;
  EXPECT_NE(ops::linear_coopmat2_unfit(caps, Tile{}), "");
  caps = h200_like();
  for (vk::CooperativeMatrixFlexibleShape& s : caps.cooperative_matrix2_facts->flexible_shapes) s.saturating = true;
  EXPECT_NE(ops::linear_coopmat2_unfit(caps, Tile{}), "");
  caps = h200_like();
  for (vk::CooperativeMatrixFlexibleShape& s : caps.cooperative_matrix2_facts->flexible_shapes)
    s.scope = VK_SCOPE_SUBGROUP_KHR;
  EXPECT_NE(ops::linear_coopmat2_unfit(caps, Tile{}), "");
}

TEST(LinearCoopmat2Fit, ShaderEmbedded) {
  const std::vector<std::string> names = vk::shader_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "linalg/linear_coopmat2"), names.end());
}

// Whether a linear_coopmat2 (`cm2`) or linear_coopmat pipeline exists.
bool created(vk::Context& c, const char* name) {
  bool found = false;
  c.pipelines().for_each([&](const vk::Pipeline& pl) { found = found || pl.name == name; });
  return found;
}

TEST_P(LinearTest, Coopmat2ByValue) {
  if (family() != ops::KernelFamily::coopmat) GTEST_SKIP() << "tensor-core family only";
  const std::string base = GetParam();
  ops::ScopedTuningOverride on(base + (base.empty() ? "" : ",") + "linear_coopmat2=on");
  vk::Context& c = ctx();
  const ops::DeviceTuning& t = ops::device_tuning(c.caps());
  if (!t.linear_coopmat2_unfit.empty()) {
    // Asked for where it cannot run: the KHR kernel does, and the tuning says why.
    EXPECT_NE(ops::describe_tuning(t).find("cooperative_matrix2 kernel not on this device"), std::string::npos);
    Options o;
    o.x_dtype = o.w_dtype = DType::f16;
    check(37, 45, 24, o);
    EXPECT_FALSE(created(c, "linalg/linear_coopmat2"));
    EXPECT_TRUE(created(c, "linalg/linear_coopmat"));
    GTEST_SKIP() << "no coopmat2 GEMM here: " << t.linear_coopmat2_unfit;
  }
  const int64_t tm = t.linear_coopmat2_tile.m, tn = t.linear_coopmat2_tile.n;
  Options plain;
  plain.x_dtype = plain.w_dtype = DType::f16;
  plain.bias = true;
  check(37, 45, 24, plain);  // one partial tile
  check(tm * 2 + 5, tn + 3, 3 * t.linear_coopmat2_tile.k + 5, plain);  // K not a multiple of the step
  Options odd = plain;  // every base offset off its 16-byte boundary, padded rows, batches with their own weights
  odd.x_lead = 3, odd.w_lead = 5, odd.y_lead = 1, odd.x_pad = 3, odd.y_pad = 2;
  odd.batch = 2, odd.shared_weight = false, odd.per_item_vectors = true;
  odd.modulation = odd.gate = true;
  odd.act = Activation::gelu_tanh;
  odd.bias_dtype = DType::bf16;
  check(tm + 7, tn * 2 + 1, 40, odd);
  Options res = plain;
  res.residual = res.in_place = true;
  res.act = Activation::silu;
  check(tm + 1, 45, 33, res);
  EXPECT_TRUE(created(c, "linalg/linear_coopmat2"));
}

}  // namespace
}  // namespace dvs
