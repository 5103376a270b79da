// The device-tuning seam (tensor/kernel_tuning.hpp): which table entry faked device property lists get, the
// DVS_TUNING / ScopedTuningOverride strings, the lanes a subgroup size allows, and `dvs info` printing the
// choice. select_tuning() is pure, so these cases do not depend on the test device or on DVS_TUNING.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "dvs/error.hpp"
#include "support/gpu.hpp"
#include "support/process.hpp"
#include "tensor/coopmat_layout.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_elementwise.hpp"

namespace dvs {
namespace {

using ops::KernelFamily;

vk::DeviceCaps cpu_device() {
  vk::DeviceCaps c;
  c.name = "faked llvmpipe";
  c.type = VK_PHYSICAL_DEVICE_TYPE_CPU;
  c.subgroup_size = 8;
  c.subgroup_shuffle = true;
  return c;
}

vk::DeviceCaps discrete_gpu() {
  vk::DeviceCaps c;
  c.name = "faked discrete GPU";
  c.type = VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU;
  c.vendor_id = 0x10de;
  c.subgroup_size = 32;
  c.subgroup_shuffle = true;
  c.max_compute_shared_memory = 48 * 1024;
  c.max_workgroup_invocations = 1024;
  return c;
}

vk::CooperativeMatrixShape shape(uint32_t m, uint32_t n, uint32_t k, VkComponentTypeKHR ab, VkComponentTypeKHR cr,
                                 VkScopeKHR scope = VK_SCOPE_SUBGROUP_KHR) {
  vk::CooperativeMatrixShape s;
  s.m = m, s.n = n, s.k = k;
  s.a = s.b = ab;
  s.c = s.result = cr;
  s.scope = scope;
  return s;
}

// What an H100 lists (driver 580), in its order: the f16 -> f32 16x16x16 shape among others.
vk::DeviceCaps coopmat_gpu() {
  vk::DeviceCaps c = discrete_gpu();
  c.cooperative_matrix = true;
  c.cooperative_matrix_shapes = {shape(16, 8, 16, VK_COMPONENT_TYPE_FLOAT16_KHR, VK_COMPONENT_TYPE_FLOAT16_KHR),
                                 shape(16, 16, 32, VK_COMPONENT_TYPE_SINT8_KHR, VK_COMPONENT_TYPE_SINT32_KHR),
                                 shape(16, 16, 16, VK_COMPONENT_TYPE_FLOAT16_KHR, VK_COMPONENT_TYPE_FLOAT32_KHR),
                                 shape(16, 16, 8, VK_COMPONENT_TYPE_FLOAT16_KHR, VK_COMPONENT_TYPE_FLOAT32_KHR)};
  return c;
}

void expect_families(const ops::DeviceTuning& t, KernelFamily k) {
  EXPECT_EQ(t.linear, k) << ops::kernel_family_name(t.linear);
  EXPECT_EQ(t.attention, k) << ops::kernel_family_name(t.attention);
  EXPECT_EQ(t.conv, k) << ops::kernel_family_name(t.conv);
}

// The message of the dvs::Error `f` throws ("" when it throws none).
template <class F>
std::string error_of(F f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(KernelTuning, CpuDeviceGetsCpuSimd) {
  const ops::DeviceTuning t = ops::select_tuning(cpu_device(), "");
  EXPECT_EQ(t.entry, "cpu-simd");
  EXPECT_EQ(t.overrides, "");
  expect_families(t, KernelFamily::texel);
  EXPECT_TRUE(t.norm_row_per_invocation);
  EXPECT_TRUE(t.eltwise_texel_inputs);
  EXPECT_TRUE(t.attention_rows_by_head_dim);
  EXPECT_EQ(t.reduce_min_chunk, 1024);
  EXPECT_EQ(t.gemm_lanes, 0);
  EXPECT_FALSE(t.coopmat.defined());
  // Even a CPU driver that listed tensor-core shapes keeps its texel kernels.
  vk::DeviceCaps c = cpu_device();
  c.cooperative_matrix = true;
  c.cooperative_matrix_shapes = coopmat_gpu().cooperative_matrix_shapes;
  const ops::DeviceTuning tc = ops::select_tuning(c, "");
  EXPECT_EQ(tc.entry, "cpu-simd");
  expect_families(tc, KernelFamily::texel);
}

TEST(KernelTuning, GpuWithoutCoopmatGetsTiled) {
  for (VkPhysicalDeviceType type : {VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU, VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU,
                                    VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU, VK_PHYSICAL_DEVICE_TYPE_OTHER}) {
    SCOPED_TRACE(vk::device_type_name(type));
    vk::DeviceCaps c = discrete_gpu();
    c.type = type;
    const ops::DeviceTuning t = ops::select_tuning(c, "");
    EXPECT_EQ(t.entry, "gpu");
    expect_families(t, KernelFamily::tiled);
    EXPECT_FALSE(t.norm_row_per_invocation);
    EXPECT_FALSE(t.eltwise_texel_inputs);
    EXPECT_FALSE(t.attention_rows_by_head_dim);
    EXPECT_EQ(t.reduce_min_chunk, 1024);
    EXPECT_FALSE(t.coopmat.defined());
  }
}

TEST(KernelTuning, GpuWithF16F32SubgroupShapeGetsCoopmat) {
  const ops::DeviceTuning t = ops::select_tuning(coopmat_gpu(), "");
  EXPECT_EQ(t.entry, "gpu-coopmat");
  expect_families(t, KernelFamily::coopmat);
  EXPECT_EQ(t.coopmat.m, 16u);
  EXPECT_EQ(t.coopmat.n, 16u);
  EXPECT_EQ(t.coopmat.k, 16u);  // the first qualifying shape listed, not the 16x16x8 after it
  EXPECT_FALSE(t.eltwise_texel_inputs);
  EXPECT_FALSE(t.norm_row_per_invocation);
  EXPECT_NE(ops::describe_tuning(t).find("16x16x16 f16*f16+f32"), std::string::npos) << ops::describe_tuning(t);
  // Only K = 8 offered: that shape.
  vk::DeviceCaps k8 = discrete_gpu();
  k8.cooperative_matrix = true;
  k8.cooperative_matrix_shapes = {shape(16, 16, 8, VK_COMPONENT_TYPE_FLOAT16_KHR, VK_COMPONENT_TYPE_FLOAT32_KHR)};
  const ops::DeviceTuning t8 = ops::select_tuning(k8, "");
  EXPECT_EQ(t8.entry, "gpu-coopmat");
  EXPECT_EQ(t8.coopmat.k, 8u);
}

TEST(KernelTuning, GpuWithoutAUsableShapeGetsGpu) {
  const struct {
    const char* what;
    vk::CooperativeMatrixShape s;
  } cases[] = {
      {"only s8", shape(16, 16, 32, VK_COMPONENT_TYPE_SINT8_KHR, VK_COMPONENT_TYPE_SINT32_KHR)},
      {"only 16x8x16 f16 -> f16", shape(16, 8, 16, VK_COMPONENT_TYPE_FLOAT16_KHR, VK_COMPONENT_TYPE_FLOAT16_KHR)},
      {"16x16x16 f16 -> f16", shape(16, 16, 16, VK_COMPONENT_TYPE_FLOAT16_KHR, VK_COMPONENT_TYPE_FLOAT16_KHR)},
      {"16x8x16 f16 -> f32", shape(16, 8, 16, VK_COMPONENT_TYPE_FLOAT16_KHR, VK_COMPONENT_TYPE_FLOAT32_KHR)},
      {"32x32x16 f16 -> f32", shape(32, 32, 16, VK_COMPONENT_TYPE_FLOAT16_KHR, VK_COMPONENT_TYPE_FLOAT32_KHR)},
      {"workgroup scope", shape(16, 16, 16, VK_COMPONENT_TYPE_FLOAT16_KHR, VK_COMPONENT_TYPE_FLOAT32_KHR,
                                VK_SCOPE_WORKGROUP_KHR)},
      {"f32 A/B", shape(16, 16, 16, VK_COMPONENT_TYPE_FLOAT32_KHR, VK_COMPONENT_TYPE_FLOAT32_KHR)},
  };
  for (const auto& k : cases) {
    SCOPED_TRACE(k.what);
    vk::DeviceCaps c = discrete_gpu();
    c.cooperative_matrix = true;
    c.cooperative_matrix_shapes = {k.s};
    const ops::DeviceTuning t = ops::select_tuning(c, "");
    EXPECT_EQ(t.entry, "gpu");
    expect_families(t, KernelFamily::tiled);
    EXPECT_FALSE(t.coopmat.defined());
  }
  // A mixed A/B pair (f16 x s8) is not the shape either.
  vk::DeviceCaps c = discrete_gpu();
  c.cooperative_matrix = true;
  vk::CooperativeMatrixShape mixed = shape(16, 16, 16, VK_COMPONENT_TYPE_FLOAT16_KHR, VK_COMPONENT_TYPE_FLOAT32_KHR);
  mixed.b = VK_COMPONENT_TYPE_SINT8_KHR;
  c.cooperative_matrix_shapes = {mixed};
  EXPECT_EQ(ops::select_tuning(c, "").entry, "gpu");
}

// Shapes listed but the feature off (extension without cooperativeMatrix): no tensor cores.
TEST(KernelTuning, CooperativeMatrixFeatureOffMeansNoCoopmat) {
  vk::DeviceCaps c = coopmat_gpu();
  c.cooperative_matrix = false;
  const ops::DeviceTuning t = ops::select_tuning(c, "");
  EXPECT_EQ(t.entry, "gpu");
  expect_families(t, KernelFamily::tiled);
  EXPECT_FALSE(t.coopmat.defined());
  // Forcing the coopmat entry or family on such a device still gives tiled kernels.
  const ops::DeviceTuning forced = ops::select_tuning(c, "gpu-coopmat,attention=coopmat");
  EXPECT_EQ(forced.entry, "gpu-coopmat");
  expect_families(forced, KernelFamily::tiled);
  // The same on a CPU device forced onto the coopmat entry (DVS_TUNING=gpu-coopmat on lavapipe).
  expect_families(ops::select_tuning(cpu_device(), "gpu-coopmat"), KernelFamily::tiled);
}

TEST(KernelTuning, OverrideStrings) {
  // An entry: the gpu entry on a CPU device (the CI pass on lavapipe).
  const ops::DeviceTuning g = ops::select_tuning(cpu_device(), "gpu");
  EXPECT_EQ(g.entry, "gpu");
  EXPECT_EQ(g.overrides, "gpu");
  expect_families(g, KernelFamily::tiled);
  EXPECT_FALSE(g.norm_row_per_invocation);
  EXPECT_FALSE(g.eltwise_texel_inputs);
  EXPECT_EQ(g.gemm_lanes, 0);  // lanes stay the device's: subgroups of 8
  // ... and the CPU entry on a GPU.
  expect_families(ops::select_tuning(coopmat_gpu(), "cpu-simd"), KernelFamily::texel);

  // Fields of the matched entry.
  const ops::DeviceTuning f =
      ops::select_tuning(cpu_device(), "linear=tiled,attention=tiled,norm_row_per_invocation=off,reduce_min_chunk=4096");
  EXPECT_EQ(f.entry, "cpu-simd");
  EXPECT_EQ(f.linear, KernelFamily::tiled);
  EXPECT_EQ(f.attention, KernelFamily::tiled);
  EXPECT_EQ(f.conv, KernelFamily::texel);
  EXPECT_FALSE(f.norm_row_per_invocation);
  EXPECT_TRUE(f.eltwise_texel_inputs);
  EXPECT_EQ(f.reduce_min_chunk, 4096);

  // An entry, then fields (the order of items does not matter for the entry: fields apply after it).
  for (const char* s : {"gpu,eltwise_texel_inputs=on,linear_tile_m=32", "eltwise_texel_inputs=on,gpu,linear_tile_m=32"}) {
    SCOPED_TRACE(s);
    const ops::DeviceTuning e = ops::select_tuning(cpu_device(), s);
    EXPECT_EQ(e.entry, "gpu");
    EXPECT_TRUE(e.eltwise_texel_inputs);
    EXPECT_FALSE(e.norm_row_per_invocation);
    EXPECT_EQ(e.linear_tile_m, 32);
    EXPECT_EQ(e.linear, KernelFamily::tiled);
  }

  // coopmat=off: every coopmat family becomes tiled, the rest stays.
  const ops::DeviceTuning off = ops::select_tuning(coopmat_gpu(), "coopmat=off");
  EXPECT_EQ(off.entry, "gpu-coopmat");
  expect_families(off, KernelFamily::tiled);
  EXPECT_FALSE(off.coopmat.defined());
  EXPECT_NE(ops::describe_tuning(off).find("tensor cores: none"), std::string::npos);
  const ops::DeviceTuning one = ops::select_tuning(coopmat_gpu(), "conv=texel,coopmat=off");
  EXPECT_EQ(one.conv, KernelFamily::texel);
  EXPECT_EQ(one.linear, KernelFamily::tiled);
  // One family off tensor cores, the others on.
  const ops::DeviceTuning lin = ops::select_tuning(coopmat_gpu(), "linear=tiled");
  EXPECT_EQ(lin.linear, KernelFamily::tiled);
  EXPECT_EQ(lin.attention, KernelFamily::coopmat);

  // Empty items are ignored.
  EXPECT_EQ(ops::select_tuning(cpu_device(), ",gpu,").entry, "gpu");
}

TEST(KernelTuning, BadOverridesThrowAndListTheFields) {
  for (const char* s : {"no-such-entry", "linear=fast", "frobnicate=1", "norm_row_per_invocation=maybe",
                        "coopmat=on", "reduce_min_chunk=1026", "reduce_min_chunk=512", "linear_tile_m=4",
                        "conv_pack_columns=-1", "linear_tile_k=", "coopmat=12x16x16", "coopmat=16x16",
                        "coopmat=16x16x16x", "linear_coopmat=2x4x4x2", "linear_coopmat=2x4x4x2x32x1",
                        "conv_coopmat=2x0x2x2x32", "coopmat_lanes=24", "attention_coopmat_subgroups=0",
                        "linear_coopmat_by_shape=", "linear_coopmat_by_shape=n>=9216", "linear_coopmat_by_shape=:2x2x2x2x32",
                        "linear_coopmat_by_shape=n>9216:2x2x2x2x32", "linear_coopmat_by_shape=n>=0:2x2x2x2x32",
                        "linear_coopmat_by_shape=n>=8&n>=9:2x2x2x2x32", "linear_coopmat_by_shape=n>=8:2x2x2x2x32+",
                        "linear_coopmat_by_shape=m<=8:2x2x2x2"}) {
    SCOPED_TRACE(s);
    const std::string e = error_of([&] { ops::select_tuning(cpu_device(), s); });
    ASSERT_FALSE(e.empty()) << "no error";
    EXPECT_NE(e.find("DVS_TUNING"), std::string::npos) << e;
  }
  // A bad name lists the entries and every field with its values.
  for (const char* s : {"no-such-entry", "frobnicate=1"}) {
    const std::string e = error_of([&] { ops::select_tuning(cpu_device(), s); });
    for (const char* want : {"cpu-simd", "gpu-coopmat", "linear=texel|tiled|coopmat", "norm_row_per_invocation=on|off",
                             "eltwise_texel_inputs", "reduce_min_chunk", "coopmat=off"})
      EXPECT_NE(e.find(want), std::string::npos) << s << ": no " << want << " in\n" << e;
  }
  // A bad value names the accepted ones.
  const std::string v = error_of([] { ops::select_tuning(cpu_device(), "attention=fast"); });
  EXPECT_NE(v.find("texel|tiled|coopmat"), std::string::npos) << v;
  EXPECT_EQ(ops::tuning_field_names().find("  an entry: cpu-simd gpu-coopmat gpu\n"), 0u) << ops::tuning_field_names();
}

// The GEMM's per-shape tile table: rows parsed in order, the first match picks a call's layout (N at least, M at
// most, both), the rest get linear_coopmat; `dvs info` lists the rows; a row the device cannot hold is an error
// naming it (where the family runs on tensor cores); "none" empties it.
TEST(KernelTuning, LinearPerShapeTileTable) {
  const ops::DeviceTuning t = ops::select_tuning(
      coopmat_gpu(), "linear_coopmat=2x4x4x2x32,linear_coopmat_by_shape=n>=9216:2x2x4x4x32+m<=256&n>=64:2x2x2x2x32");
  ASSERT_EQ(t.linear_coopmat_by_shape.size(), 2u);
  EXPECT_EQ(t.linear_coopmat_by_shape[0].min_n, 9216);
  EXPECT_EQ(t.linear_coopmat_by_shape[0].max_m, 0);
  EXPECT_EQ(t.linear_coopmat_by_shape[1].min_n, 64);
  EXPECT_EQ(t.linear_coopmat_by_shape[1].max_m, 256);
  auto tile_of = [&](int64_t m, int64_t n) { return ops::linear_coopmat_layout(t, m, n).tile; };
  EXPECT_EQ(tile_of(35552, 12288).frags_n, 4);   // row 1
  EXPECT_EQ(tile_of(35552, 9216).frags_n, 4);    // row 1, at its bound
  EXPECT_EQ(tile_of(200, 12288).frags_n, 4);     // both match: the first wins
  EXPECT_EQ(tile_of(256, 3072).sg_n, 2);         // row 2, at its M bound
  EXPECT_EQ(tile_of(257, 3072).sg_n, 4);         // past it: linear_coopmat
  EXPECT_EQ(tile_of(100, 63).sg_n, 4);           // N under row 2's bound
  const std::string d = ops::describe_tuning(t);
  EXPECT_NE(d.find("(n>=9216:2x2x4x4x32) (n>=64&m<=256:2x2x2x2x32)"), std::string::npos) << d;
  // A row past the device's shared memory (8 x 8 fragments of 16x16 per subgroup) is refused by name.
  const std::string e =
      error_of([] { ops::select_tuning(coopmat_gpu(), "gpu-coopmat,linear_coopmat_by_shape=n>=8:4x4x8x8x64"); });
  EXPECT_NE(e.find("linear_coopmat_by_shape row n>=8:4x4x8x8x64 does not fit"), std::string::npos) << e;
  // Off tensor cores the rows are not used, so not checked.
  EXPECT_NO_THROW(ops::select_tuning(discrete_gpu(), "linear_coopmat_by_shape=n>=8:4x4x8x8x64"));
  EXPECT_TRUE(ops::select_tuning(coopmat_gpu(), "linear_coopmat_by_shape=n>=8:2x2x2x2x32,linear_coopmat_by_shape=none")
                  .linear_coopmat_by_shape.empty());
  EXPECT_TRUE(ops::select_tuning(coopmat_gpu(), "").linear_coopmat_by_shape.empty());  // no row is measured yet
}

// The tensor-core layout fields: taken as given (the layout is checked against the device: a misfit runs tiled
// and says why; coopmat_pipeline refuses it with the same words), the rest chosen from the table.
TEST(KernelTuning, CoopmatLayoutFields) {
  const ops::DeviceTuning t = ops::select_tuning(
      coopmat_gpu(), "linear_coopmat=1x2x4x2x16,conv_coopmat=2x2x2x2x32,attention_coopmat_subgroups=2,coopmat=16x16x8");
  EXPECT_EQ(t.linear_coopmat.sg_m, 1);
  EXPECT_EQ(t.linear_coopmat.sg_n, 2);
  EXPECT_EQ(t.linear_coopmat.frags_m, 4);
  EXPECT_EQ(t.linear_coopmat.frags_n, 2);
  EXPECT_EQ(t.linear_coopmat.k, 16);
  EXPECT_EQ(t.conv_coopmat.subgroups(), 4);
  EXPECT_EQ(t.attention_coopmat_subgroups, 2);
  EXPECT_EQ(t.coopmat.k, 8u);
  expect_families(t, KernelFamily::coopmat);
  const std::string d = ops::describe_tuning(t);
  EXPECT_NE(d.find("64x64x16 (1x2 subgroups of 32 lanes, 4x2 fragments of 16x16x8 each)"), std::string::npos) << d;
  EXPECT_NE(d.find("32 query rows x 64 keys (2 subgroups of 32 lanes"), std::string::npos) << d;
  // Lanes other than the device's: the tensor-core kernels cannot run (tiled, and why).
  const ops::DeviceTuning l = ops::select_tuning(coopmat_gpu(), "coopmat_lanes=16");
  expect_families(l, KernelFamily::tiled);
  EXPECT_NE(l.conv_unfit.find("subgroups of 16 lanes; faked discrete GPU has 32"), std::string::npos) << l.conv_unfit;
  // A layout whose index maps do not divide (K 12 is no multiple of 8).
  const ops::DeviceTuning k = ops::select_tuning(coopmat_gpu(), "linear_coopmat=2x4x4x2x12");
  EXPECT_EQ(k.linear, KernelFamily::tiled);
  EXPECT_EQ(k.attention, KernelFamily::coopmat);
  EXPECT_NE(k.linear_unfit.find("does not divide"), std::string::npos) << k.linear_unfit;
}

// device_tuning() applies DVS_TUNING (whatever this process has; the CI pass sets DVS_TUNING=gpu), then the
// in-process override, and restores the previous one when the override's scope ends.
TEST(KernelTuning, DeviceTuningPicksUpScopedOverride) {
  const vk::DeviceCaps c = cpu_device();
  const char* env = std::getenv("DVS_TUNING");
  const std::string outer = ops::device_tuning(c).entry;
  EXPECT_EQ(outer, ops::select_tuning(c, env ? env : "").entry);
  const bool outer_rows = ops::device_tuning(c).norm_row_per_invocation;
  {
    ops::ScopedTuningOverride a("gpu");
    EXPECT_EQ(ops::device_tuning(c).entry, "gpu");
    EXPECT_FALSE(ops::device_tuning(c).norm_row_per_invocation);
    {
      ops::ScopedTuningOverride b("cpu-simd,eltwise_texel_inputs=off");
      EXPECT_EQ(ops::device_tuning(c).entry, "cpu-simd");
      EXPECT_TRUE(ops::device_tuning(c).norm_row_per_invocation);
      EXPECT_FALSE(ops::device_tuning(c).eltwise_texel_inputs);
    }
    EXPECT_EQ(ops::device_tuning(c).entry, "gpu");  // the outer override again
  }
  EXPECT_EQ(ops::device_tuning(c).entry, outer);
  EXPECT_EQ(ops::device_tuning(c).norm_row_per_invocation, outer_rows);
  // Fields alone keep the entry the device (and DVS_TUNING) chose.
  {
    ops::ScopedTuningOverride f("norm_row_per_invocation=on");
    EXPECT_EQ(ops::device_tuning(c).entry, outer);
    EXPECT_TRUE(ops::device_tuning(c).norm_row_per_invocation);
  }
  // A bad in-process override throws at use, like a bad DVS_TUNING.
  {
    ops::ScopedTuningOverride bad("norm_row_per_invocation=sometimes");
    EXPECT_THROW(ops::device_tuning(c), Error);
  }
  EXPECT_EQ(ops::device_tuning(c).entry, outer);
}

TEST(KernelTuning, GemmLanesFollowTheSubgroup) {
  const struct {
    uint32_t size;
    bool shuffle;
    int lanes;
  } cases[] = {{8, true, 0}, {16, true, 1}, {32, true, 1}, {64, true, 1}, {4, true, 2},
               {128, true, 2}, {8, false, 2}, {32, false, 2}, {0, true, 2}};
  for (const auto& k : cases) {
    SCOPED_TRACE("subgroup " + std::to_string(k.size) + (k.shuffle ? " with" : " without") + " shuffle");
    for (vk::DeviceCaps c : {cpu_device(), discrete_gpu(), coopmat_gpu()}) {
      c.subgroup_size = k.size;
      c.subgroup_shuffle = k.shuffle;
      EXPECT_EQ(ops::select_tuning(c, "").gemm_lanes, k.lanes) << c.name;
      EXPECT_EQ(ops::select_tuning(c, "gpu").gemm_lanes, k.lanes) << c.name;
      EXPECT_EQ(ops::gemm_lanes(c), k.lanes) << c.name;
      // The conv tile takes the device's lanes.
      EXPECT_EQ(ops::conv_tile(c, DType::bf16, 4096, 512).lanes, k.lanes) << c.name;
    }
  }
}

// The test device: the elementwise ops read texel buffers where its tuning says so, and the "gpu" entry
// (the CI pass on lavapipe) runs the vec4 storage-buffer shaders (checked by value by the .../storage cases
// of the Ops*/Split* elementwise, layout and check tests).
using KernelTuningDevice = test::GpuTest;

TEST_F(KernelTuningDevice, ElementwiseInputsFollowTheTuning) {
  const vk::DeviceCaps& caps = ctx().caps();
  EXPECT_EQ(ops::texel_inputs(caps), ops::device_tuning(caps).eltwise_texel_inputs);
  {
    ops::ScopedTuningOverride gpu("gpu");
    EXPECT_FALSE(ops::texel_inputs(caps));
  }
  {
    ops::ScopedTuningOverride cpu("cpu-simd");
    EXPECT_TRUE(ops::texel_inputs(caps));
  }
  EXPECT_NE(ops::describe_tuning(ops::device_tuning(caps)).find("Kernel tuning: entry \"" + ops::device_tuning(caps).entry),
            std::string::npos);
}

TEST(KernelTuning, DvsInfoPrintsTheChoice) {
  const std::string dvs = test::program("dvs");
  const auto r = test::run_command(dvs + " info");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Kernel tuning: entry"), std::string::npos) << r.output;
  // DVS_TUNING is shown as applied.
  const auto g = test::run_command("DVS_TUNING=gpu,reduce_min_chunk=2048 " + dvs + " info");
  ASSERT_EQ(g.exit_code, 0) << g.output;
  EXPECT_NE(g.output.find("Kernel tuning: entry \"gpu\" with overrides \"gpu,reduce_min_chunk=2048\""),
            std::string::npos)
      << g.output;
  EXPECT_NE(g.output.find("partials of at least 2048 elements"), std::string::npos) << g.output;
  // A bad DVS_TUNING is an error that lists the fields.
  const auto bad = test::run_command("DVS_TUNING=linear=fast " + dvs + " info");
  EXPECT_NE(bad.exit_code, 0) << bad.output;
  EXPECT_NE(bad.output.find("texel|tiled|coopmat"), std::string::npos) << bad.output;
}

}  // namespace
}  // namespace dvs
