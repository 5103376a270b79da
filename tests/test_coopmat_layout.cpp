// The tensor-core kernels' layouts (tensor/coopmat_layout.hpp): shared memory against hand counts of the shaders'
// arrays, the index maps' divisibility rules, the device limits each layout is checked against (with errors that
// name the limit and the DVS_TUNING field), the pipeline that requires the subgroup size, and the kernel census
// that the tensor-core pass (tests/run_coopmat_pass.sh) reads.
#include <gtest/gtest.h>

#include <string>

#include "dvs/error.hpp"
#include "io/host_tensor.hpp"
#include "support/gpu.hpp"
#include "tensor/coopmat_layout.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_linear.hpp"
#include "vk/pipeline.hpp"

namespace dvs {
namespace {

using ops::CoopmatAttention;
using ops::CoopmatGemm;

constexpr ops::CoopmatShape k16{16, 16, 16}, k8{8, 8, 8};

// A GPU with subgroup size control from 32 to 64 (requirable for compute), 48 KiB, 1024 invocations.
vk::DeviceCaps gpu() {
  vk::DeviceCaps c;
  c.name = "faked GPU";
  c.type = VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU;
  c.subgroup_size = 32;
  c.subgroup_size_control = c.compute_required_subgroup_size = true;
  c.min_subgroup_size = 32;
  c.max_subgroup_size = 64;
  c.max_compute_workgroup_subgroups = 16;
  c.max_compute_shared_memory = 48 * 1024;
  c.max_workgroup_invocations = 1024;
  return c;
}

TEST(CoopmatLayout, SharedMemoryOfTheShaders) {
  // linear_coopmat.comp: sx, sw [2 stages][128 rows][40 halves] and stage [8 subgroups][16 x 16] floats.
  const CoopmatGemm lin{k16, 32, {2, 4, 4, 2, 32}};
  EXPECT_EQ(ops::linear_coopmat_shared_bytes(lin), 2u * 2 * 128 * 40 * 2 + 8 * 256 * 4);
  // conv_coopmat.comp: As, Bs [128][40] halves (one stage) and Stage [8][256] floats: 28 KiB.
  const CoopmatGemm conv{k16, 32, {4, 2, 2, 4, 32}};
  EXPECT_EQ(ops::conv_coopmat_shared_bytes(conv), 28u * 1024);
  // Two stages of As, Bs: 48 KiB, which a 48 KiB GPU holds and lavapipe's 32 KiB does not (one stage there).
  EXPECT_EQ(ops::conv_coopmat_shared_bytes(conv, 2), 48u * 1024);
  EXPECT_EQ(ops::conv_coopmat_stages(gpu(), conv, true), 2);
  EXPECT_EQ(ops::conv_coopmat_stages(gpu(), conv, false), 1);
  vk::DeviceCaps small = gpu();
  small.max_compute_shared_memory = 32 << 10;
  EXPECT_EQ(ops::conv_coopmat_stages(small, conv, true), 1);
  // At 8x8 fragments the same arrangement holds 64 x 64 and 64-float staging.
  const CoopmatGemm conv8{k8, 8, {4, 2, 2, 4, 32}};
  EXPECT_EQ(conv8.tile_m(), 64);
  EXPECT_EQ(conv8.tile_n(), 64);
  EXPECT_EQ(ops::conv_coopmat_shared_bytes(conv8), 2u * 64 * 40 * 2 + 8 * 64 * 4);
  // attention: sK, sV [64 keys][D + 8] halves; sS [4 x 16 rows][64 + 4] floats; sP [4 x 16 rows][64 + 8] halves
  // (every row padded by 16 bytes against bank conflicts); the twin adds sQ [64 rows][D] halves and xch [128] floats.
  const CoopmatAttention att{k16, 32, 4, 64};
  EXPECT_EQ(ops::attention_coopmat_shared_bytes(att, 64), 2u * 64 * 72 * 2 + 64 * 68 * 4 + 64 * 72 * 2);
  EXPECT_EQ(ops::attention_coopmat_shared_bytes(att, 32, ops::AttentionKernel::twin),
            ops::attention_coopmat_shared_bytes(att, 32) + 64u * 32 * 2 + 128 * 4);
  // The coopmat2 variant: K and V, and one [16 rows][16 + 4] fp32 block of Q / O staging per subgroup. So 8
  // subgroups (128 query rows) take 28 KiB, where the KHR kernel would need 70 KiB.
  const CoopmatAttention att8{k16, 32, 8, 64};
  EXPECT_EQ(ops::attention_coopmat_shared_bytes(att8, 64, ops::AttentionKernel::coopmat2),
            2u * 64 * 72 * 2 + 8 * 16 * 20 * 4);
  EXPECT_EQ(ops::attention_coopmat_shared_bytes(att8, 64, ops::AttentionKernel::coopmat2), 28u * 1024);
  EXPECT_EQ(ops::attention_coopmat_shared_bytes(att8, 64), 70u * 1024);
}

TEST(CoopmatLayout, TheGpuLayoutsFitTheGpu) {
  EXPECT_EQ(ops::linear_coopmat_unfit(gpu(), {k16, 32, {2, 4, 4, 2, 32}}), "");
  EXPECT_EQ(ops::conv_coopmat_unfit(gpu(), {k16, 32, {4, 2, 2, 4, 32}}, false), "");
  EXPECT_EQ(ops::attention_coopmat_unfit(gpu(), {k16, 32, 4, 64}, 64, ops::AttentionKernel::khr), "");
  // 128 query rows: the coopmat2 variant fits 48 KiB, the KHR kernel does not.
  EXPECT_EQ(ops::attention_coopmat_unfit(gpu(), {k16, 32, 8, 64}, 64, ops::AttentionKernel::coopmat2), "");
  EXPECT_NE(ops::attention_coopmat_unfit(gpu(), {k16, 32, 8, 64}, 64, ops::AttentionKernel::khr).find("shared memory"),
            std::string::npos);
  // 64 lanes through size control (512 invocations, 8 subgroups).
  EXPECT_EQ(ops::linear_coopmat_unfit(gpu(), {k16, 64, {2, 4, 4, 2, 32}}), "");
}

TEST(CoopmatLayout, DeviceLimitsNameTheLimitAndTheField) {
  vk::DeviceCaps c = gpu();
  c.max_compute_shared_memory = 32 * 1024;
  std::string e = ops::linear_coopmat_unfit(c, {k16, 32, {2, 4, 4, 2, 32}});
  EXPECT_NE(e.find("needs 49152 bytes of shared memory; faked GPU has 32768 (maxComputeSharedMemorySize)"),
            std::string::npos) << e;
  EXPECT_NE(e.find("linear_coopmat"), std::string::npos) << e;
  // Subgroups outside the device's sizes (16 lanes; the device runs 32..64).
  e = ops::conv_coopmat_unfit(gpu(), {k16, 16, {4, 2, 2, 4, 32}}, false);
  EXPECT_NE(e.find("subgroups of 16 lanes"), std::string::npos) << e;
  // ... which the twin, emulating its lanes, does not need.
  EXPECT_EQ(ops::conv_coopmat_unfit(gpu(), {k16, 16, {4, 2, 2, 4, 32}}, true), "");
  // Subgroups per workgroup, then invocations.
  c = gpu();
  c.max_compute_workgroup_subgroups = 4;
  e = ops::linear_coopmat_unfit(c, {k16, 32, {2, 4, 4, 2, 32}});
  EXPECT_NE(e.find("8 subgroups per workgroup; faked GPU allows 4 (maxComputeWorkgroupSubgroups)"), std::string::npos) << e;
  c.max_workgroup_invocations = 128;
  e = ops::linear_coopmat_unfit(c, {k16, 32, {2, 4, 4, 2, 32}});
  EXPECT_NE(e.find("256 invocations; faked GPU allows 128 per workgroup"), std::string::npos) << e;
}

TEST(CoopmatLayout, IndexMapsMustDivide) {
  // linear: K a multiple of 8 and of the fragment's K; invocations a multiple of K; M, N multiples of the rows
  // staged per pass.
  EXPECT_NE(ops::linear_coopmat_unfit(gpu(), {k16, 32, {2, 4, 4, 2, 24}}).find("does not divide"), std::string::npos);
  EXPECT_NE(ops::linear_coopmat_unfit(gpu(), {k16, 32, {1, 1, 1, 1, 64}}).find("does not divide"), std::string::npos);
  EXPECT_EQ(ops::linear_coopmat_unfit(gpu(), {k16, 32, {1, 1, 1, 1, 32}}), "");
  // conv: invocations and tile sides divide one another; K / 4 a multiple of their quotient.
  EXPECT_EQ(ops::conv_coopmat_unfit(gpu(), {k16, 32, {2, 2, 2, 2, 32}}, false), "");   // 128 = 64 x 2 invocations
  EXPECT_NE(ops::conv_coopmat_unfit(gpu(), {k16, 32, {2, 2, 2, 2, 8}}, false).find("does not divide"),
            std::string::npos);  // K 8 is no multiple of the fragment's 16
  EXPECT_NE(ops::conv_coopmat_unfit(gpu(), {k16, 32, {3, 1, 1, 1, 32}}, false).find("does not divide"),
            std::string::npos);  // 96 invocations over 48 pixels x 16 channels: 96 / 16 = 6 does not divide 8
  // The twin needs its lanes to divide a fragment.
  EXPECT_NE(ops::conv_coopmat_unfit(gpu(), {k8, 128, {1, 1, 1, 1, 32}}, true).find("lanes dividing a fragment"),
            std::string::npos);
  // attention: head_dim a multiple of the fragment's K and N and of 4 x lanes per row, at most the key tile.
  const CoopmatAttention a{k16, 32, 4, 64};
  EXPECT_EQ(ops::attention_coopmat_head_dim_unfit(a, 16), "");
  EXPECT_EQ(ops::attention_coopmat_head_dim_unfit(a, 40),
            "head_dim 40: the tensor-core kernel takes multiples of 16 up to 64 (fragments 16x16x16, 32 lanes, "
            "64-key tiles)");
  EXPECT_NE(ops::attention_coopmat_head_dim_unfit(a, 128).find("multiples of 16 up to 64"), std::string::npos);
  EXPECT_NE(ops::attention_coopmat_head_dim_unfit(a, 80).find("head_dim 80"), std::string::npos);
  EXPECT_EQ(ops::attention_coopmat_head_dim_unfit({k8, 8, 4, 64}, 40), "");  // 8x8x8 fragments take 40
  // 64 lanes over 16 rows: 4 lanes per row, so head_dim a multiple of 16.
  EXPECT_EQ(ops::attention_coopmat_head_dim_unfit({k16, 64, 2, 64}, 48), "");
  EXPECT_NE(ops::attention_coopmat_head_dim_unfit({{16, 16, 8}, 64, 2, 64}, 40).find("multiples of 16"), std::string::npos);
  EXPECT_NE(ops::attention_coopmat_head_dim_unfit({{8, 8, 8}, 32, 2, 64}, 8).find("multiples of 16"), std::string::npos);
  // Keys per tile a multiple of the fragment's N and K.
  EXPECT_NE(ops::attention_coopmat_unfit(gpu(), {k16, 32, 2, 40}, 16, ops::AttentionKernel::khr).find("does not divide"),
            std::string::npos);
}

class CoopmatLayoutDevice : public test::GpuTest {};

// PipelineCache::get with a required subgroup size: created (through size control where the device has it) at
// the device's size, refused with both sizes named otherwise. Then the pipeline runs.
TEST_F(CoopmatLayoutDevice, PipelineRequiresTheSubgroupSize) {
  vk::Context& c = ctx();
  const uint32_t lanes = c.caps().subgroup_size;
  const uint32_t spec[] = {2 * lanes, 0x40000000u /* 2.0f */, 1};
  const uint32_t other = lanes == 128 ? 64 : (c.caps().subgroup_size_control ? c.caps().max_subgroup_size * 2 : lanes * 2);
  try {
    c.pipelines().get("test/spec_constants", spec, other);
    ADD_FAILURE() << "no error for " << other << " lanes";
  } catch (const Error& e) {
    const std::string w = e.what();
    EXPECT_NE(w.find("laid out for subgroups of " + std::to_string(other) + " lanes"), std::string::npos) << w;
    EXPECT_NE(w.find(c.caps().name), std::string::npos) << w;
  }
  const vk::Pipeline& p = c.pipelines().get("test/spec_constants", spec, lanes);
  const uint32_t n = 5 * lanes;
  std::vector<float> in(n), out(n);
  for (uint32_t i = 0; i < n; ++i) in[i] = float(i);
  Tensor x = Tensor::upload(c, HostTensor::from_f32({int64_t(n)}, in));
  Tensor y = Tensor::empty(c, {int64_t(n)}, DType::f32);
  struct {
    uint32_t n;
    float bias;
  } push{n, 0.5f};
  ops::run_now(c, [&](vk::Recorder& rec) { rec.dispatch(p, {x.buffer(), y.buffer()}, &push, sizeof push, 3); });
  out = y.download(c).to_f32();
  for (uint32_t i = 0; i < n; ++i) ASSERT_EQ(out[i], 2.0f * float(i) + 1.5f) << i;
}

// coopmat_pipeline refuses a layout the device cannot hold with the reason, before any pipeline is made.
TEST_F(CoopmatLayoutDevice, CoopmatPipelineRefusesAMisfit) {
  vk::Context& c = ctx();
  const size_t made = c.pipelines().pipelines_created();
  const std::string why = "needs 99999 bytes of shared memory";
  try {
    ops::coopmat_pipeline(c, "linalg/linear_coopmat", {}, 32, why);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "linalg/linear_coopmat: " + why);
  }
  EXPECT_EQ(c.pipelines().pipelines_created(), made);
}

// The census: a call that falls back from a coopmat family for a reason of the device is noted as such (the
// tensor-core pass fails such a test); a call that asked for tiled is not a fallback. A layout no device holds
// (lanes 4) makes the fallback on any device.
TEST_F(CoopmatLayoutDevice, CensusNotesDeviceFallbacks) {
  vk::Context& c = ctx();
  auto calls = [&](bool device_fallback) {
    uint64_t n = 0;
    for (const auto& [note, count] : c.kernel_notes())
      if (note.op == "linear" && note.device == device_fallback && !note.fallback.empty() == device_fallback) n += count;
    return n;
  };
  std::vector<float> xv(12 * 8, 0.25f), wv(5 * 8, 0.5f);
  Tensor x = Tensor::upload(c, HostTensor::from_f32({12, 8}, xv));
  Tensor w = Tensor::upload(c, HostTensor::from_f32({5, 8}, wv));
  Tensor y = Tensor::empty(c, {12, 5}, DType::f32);
  const uint64_t before = calls(true), plain = calls(false);
  {
    ops::ScopedTuningOverride t("gpu-coopmat,coopmat_lanes=4");
    const std::string why = ops::device_tuning(c.caps()).linear_unfit;
    EXPECT_FALSE(why.empty());
    ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x, w, y); });
    bool found = false;
    for (const auto& [note, count] : c.kernel_notes())
      found |= note.op == "linear" && note.device && note.fallback == why && note.family == "tiled";
    EXPECT_TRUE(found) << why;
  }
  EXPECT_EQ(calls(true), before + 1);
  {
    ops::ScopedTuningOverride t("gpu-coopmat,linear=tiled");
    ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x, w, y); });
  }
  EXPECT_EQ(calls(true), before + 1);
  EXPECT_EQ(calls(false), plain + 1);
  for (float v : y.download(c).to_f32()) EXPECT_FLOAT_EQ(v, 1.0f);
  test::forgive_kernel_fallbacks();  // the fallback above was this test's purpose
}

}  // namespace
}  // namespace dvs
