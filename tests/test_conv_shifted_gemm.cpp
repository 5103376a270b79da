// The convolution as the tensor-core GEMM itself (DeviceTuning::conv_shifted_gemm, ops_conv_shifted.hpp): the input
// repacked fp16 on its zero-padded grid, nn/conv_shifted_coopmat (linear_coopmat.comp's tile and loads) with each K
// step's rows shifted by its tap's offset on the grid, the grid's padding rows dropped by the epilogue. It reads the
// same fp16 operands as the implicit-GEMM kernel (conv_coopmat.comp) and sums them in the same order (tap by tap, K
// ascending, in fragments of the device's K), so every path it takes must give that kernel's bits, which
// test_conv_families.cpp holds to a plain-C++ reference on the same pass: the causal 3x3x3 conv with and without a
// cache, 3x3, 1x1 and the 3x3 of upsample2x_conv3x3 (its grid the upsampled input's), on odd frame, row and
// column counts, 19 output channels (no whole tile), fp16 and bf16 weights
// packed at load, whole and under limits that split the call into output-channel groups and row chunks (a chunk's grid
// then starts or ends inside the image, its halo rows real rows). The path it cannot take (the stride-2 downsample)
// must still run the implicit-GEMM kernel. Runs where the device has tensor cores (the
// tensor-core pass, tests/run_coopmat_pass.sh); elsewhere there is no GEMM kernel to run it with.
#include <gtest/gtest.h>

#include <array>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "support/conv_kernel_test.hpp"
#include "support/kernel_calls.hpp"
#include "support/stored_values.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv.hpp"
#include "tensor/ops_conv_shifted.hpp"
#include "tensor/ops_conv_weights.hpp"
#include "vk/device_info.hpp"

namespace dvs {
namespace {

constexpr const char* kShader = "nn/conv_shifted_coopmat";

using test::random_stored;

class ShiftedGemmConvOps : public test::ConvKernelTest {
 protected:
  void SetUp() override {
    ConvKernelTest::SetUp();
    if (twin_) GTEST_SKIP() << "no tensor cores on " << ctx().caps().name << " (the tensor-core pass runs this)";
  }
  // y of every VAE conv path on a [2, cin, 3, 11, W] input with 19 output channels, weights packed at load as `dt`.
  std::vector<std::vector<uint32_t>> all_convs(int64_t cin, DType dt, const char* limits, int64_t W = 13) {
    vk::Context& c = ctx();
    const int64_t cout = 19, F = 3, H = 11;
    const Tensor x = random_stored(c, {2, cin, F, H, W}, 1, 1.f, DType::f32);
    const Tensor cache = random_stored(c, {2, cin, 2, H, W}, 2, 1.f, DType::f32);
    const Tensor w3 = random_stored(c, {cout, cin, 3, 3, 3}, 3, 0.2f, dt);
    const Tensor w2 = random_stored(c, {cout, cin, 3, 3}, 4, 0.2f, dt);
    const Tensor w1 = random_stored(c, {cout, cin, 1, 1, 1}, 5, 0.4f, dt);
    const Tensor b = random_stored(c, {cout}, 6, 0.5f, DType::bf16);
    std::vector<ops::PackedConvWeights> p;
    for (const Tensor* w : {&w3, &w2, &w1}) p.push_back(ops::packed_conv_weights_now(c, *w, "test weights"));
    return run_paths(test::vae_conv_paths(x, cache, p[0], p[1], p[2], b), limits);
  }
};

// The paths of vae_conv_paths() the shifted GEMM takes: every stride-1 same-size conv, upsample2x_conv3x3's among
// them (not the stride-2 downsample).
constexpr int kPathsTaken = 5;

TEST_F(ShiftedGemmConvOps, SameBitsAsTheImplicitGemmKernelOnEveryPathAndSplit) {
  struct Run {
    int64_t cin;
    DType w;
    const char* limits;
    int taken;  // paths the shifted GEMM takes
  };
  // Channels a multiple of the GEMM tile's K (32 on the tensor-core pass and the GPUs' entry). binding=16KiB and
  // 12KiB cut the 19 channels into groups and each frame into row chunks; under 8KiB one output row of the 3x3x3
  // convs at 64 channels (3 frames x 3 rows x 15 columns padded) and of the upsampling conv (3 rows x 28 columns) does
  // not fit a chunk: those three paths fall back.
  const Run runs[] = {{32, DType::f16, nullptr, kPathsTaken},
                      {64, DType::bf16, nullptr, kPathsTaken},
                      {32, DType::f16, "binding=16KiB", kPathsTaken},
                      {32, DType::bf16, "binding=12KiB", kPathsTaken},
                      {64, DType::f16, "binding=8KiB", kPathsTaken - 3}};
  for (const Run& r : runs) {
    const std::string where = "Cin " + std::to_string(r.cin) + ", " + dtype_name(r.w) + " weights packed at load" +
                              (r.limits ? std::string(" under ") + r.limits : "");
    const uint64_t before = test::kernel_calls(ctx(), kShader);
    const uint64_t implicit_before = test::kernel_calls(ctx(), gemm_name());
    ctx().reset_splits();
    expect_same_bits("conv=coopmat,conv_shifted_gemm=on", "conv=coopmat,conv_shifted_gemm=off",
                     [&] { return all_convs(r.cin, r.w, r.limits); }, where);
    // The shifted GEMM ran the paths it takes (the comparison is not one kernel against itself), the implicit-GEMM
    // kernel the others with the option on and all six with it off.
    EXPECT_EQ(test::kernel_calls(ctx(), kShader) - before, uint64_t(r.taken)) << where;
    EXPECT_EQ(test::kernel_calls(ctx(), gemm_name()) - implicit_before, uint64_t(6 + 6 - r.taken)) << where;
    // Under the limits the shifted GEMM's calls ran in chunks (the splits' grids and halos were exercised).
    if (r.limits) {
      EXPECT_EQ(ctx().splits().count("conv2d as a GEMM"), 1u) << where;
      EXPECT_EQ(ctx().splits().count("causal_conv3d as a GEMM"), 1u) << where;
    }
  }
}

// Its input repack transposed through shared memory (DeviceTuning::conv_pack_tiled) gives the same bits: the padded
// grid's halo rows and columns, the x2-upsampled grid, whole and in the row chunks of binding=12KiB (a chunk's halo
// rows real rows), and grids of two and three 64-column tiles (67 columns: 69 padded, 136 upsampled).
TEST_F(ShiftedGemmConvOps, TiledRepackSameBits) {
  const std::string on = "conv=coopmat,conv_shifted_gemm=on,conv_pack_tiled=";
  for (const auto& [w, limits] : {std::pair<int64_t, const char*>{13, nullptr}, {13, "binding=12KiB"}, {67, nullptr}}) {
    const uint64_t before = test::kernel_calls(ctx(), kShader);
    const std::string where = std::to_string(w) + " columns" + (limits ? std::string(" under ") + limits : "");
    expect_same_bits(on + "on", on + "off", [&] { return all_convs(32, DType::f16, limits, w); }, where);
    EXPECT_EQ(test::kernel_calls(ctx(), kShader) - before, uint64_t(2 * kPathsTaken)) << where;
  }
}

TEST_F(ShiftedGemmConvOps, RefusesWhatItCannotTakeAndSaysWhy) {
  vk::Context& c = ctx();
  const vk::DeviceCaps& caps = c.caps();
  const Tensor w32 = random_stored(c, {8, 32, 3, 3, 3}, 1, 0.2f, DType::f16);
  const Tensor w40 = random_stored(c, {8, 40, 3, 3, 3}, 2, 0.2f, DType::f16);
  const ops::PackedConvWeights p32 = ops::packed_conv_weights_now(c, w32, "w32");
  const ops::PackedConvWeights p40 = ops::packed_conv_weights_now(c, w40, "w40");
  ops::conv::ConvJob j;  // a causal 3x3x3 conv of [1, 32, 2, 5, 7]
  j.cin = 32, j.frames = 2, j.h = 5, j.w = 7, j.cout = 8, j.kt = 3, j.kh = 3, j.kw = 3, j.pad_top = 1, j.pad_left = 1;
  j.ho = 5, j.wo = 7, j.frames_out = 2, j.prefix = 2;
  j.ys_w = 1, j.ys_h = 7, j.ys_f = 35, j.ys_c = 70, j.ys_b = 560;
  const ops::conv::ShiftedCall call{true, true, 0, 1u << 20, nullptr};
  auto why = [&](const std::string& tuning, const ops::conv::ConvJob& job, const ops::ConvWeights& w,
                 const ops::conv::ShiftedCall& k) {
    ops::ScopedTuningOverride t(tuning);
    return ops::conv::shifted_refusal(caps, ops::device_tuning(caps), job, w, k);
  };
  const std::string on = "conv=coopmat,conv_shifted_gemm=on";
  EXPECT_EQ(why(on, j, p32, call), "");
  EXPECT_EQ(why("conv=coopmat,conv_shifted_gemm=off", j, p32, call), "off (conv_shifted_gemm)");
  EXPECT_NE(why(on, j, w32, call).find("not packed at load"), std::string::npos);
  ops::conv::ConvJob j40 = j;
  j40.cin = 40;
  EXPECT_NE(why(on, j40, p40, call).find("40 packed input channels"), std::string::npos);
  ops::conv::ConvJob strided = j;
  strided.stride = 2, strided.kt = 1, strided.prefix = 0, strided.pad_top = 0, strided.pad_left = 0, strided.ho = 2,
  strided.wo = 3;
  EXPECT_NE(why(on, strided, p32, call).find("stride 2"), std::string::npos);
  ops::conv::ConvJob up = j;  // the fused x2 upsampling's 3x3 conv: taken, on the upsampled grid
  up.upsample = true, up.kt = 1, up.prefix = 0, up.ho = 10, up.wo = 14, up.time_mode = 2, up.frames_out = 4;
  const Tensor w2 = random_stored(c, {8, 32, 3, 3}, 3, 0.2f, DType::f16);
  const ops::PackedConvWeights p2 = ops::packed_conv_weights_now(c, w2, "w2");
  EXPECT_EQ(why(on, up, p2, call), "");
  up.ho = 5;  // an output that is not the upsampled size
  EXPECT_NE(why(on, up, p2, call).find("not a same-size"), std::string::npos);
  ops::conv::ShiftedCall f32 = call;
  f32.x_f16 = false;
  EXPECT_NE(why(on, j, p32, f32).find("repacked f32"), std::string::npos);
  ops::conv::ShiftedCall twin = call;
  twin.coopmat = false;
  EXPECT_NE(why(on, j, p32, twin).find("not the tensor-core kernel"), std::string::npos);
  ops::conv::ShiftedCall tiny = call;
  tiny.input_bytes = 1024;  // not even one output row's padded input (3 frames x 3 rows x 9 columns x 32 channels)
  EXPECT_NE(why(on, j, p32, tiny).find("does not fit"), std::string::npos);
}

// The device run must time the new kernel at the sweep's real shapes, not the fallback: on the H200's facts (subgroups
// of 32 with size control, 16x16x16 fp16 -> fp32 fragments, 48 KiB of shared memory, 4 GiB bindings; bench/results/
// h200-2026-11-29-info.txt) under the tensor-core entry, the VAE's same-size convolutions at their real channel counts
// and resolutions take it, within the 128 MiB of staging a call gets (ConvScratch's cap); the 16-channel latent conv
// does not (16 is no multiple of the GEMM's K of 32), and says why.
TEST(ShiftedGemmConvChoice, TakesTheRealVaeConvolutionsOnAnH200) {
  vk::DeviceCaps caps;
  caps.name = "H200-like";
  caps.type = VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU;
  caps.vendor_id = 0x10de;
  caps.subgroup_size = 32, caps.min_subgroup_size = 32, caps.max_subgroup_size = 32;
  caps.subgroup_size_control = caps.compute_required_subgroup_size = true;
  caps.max_compute_workgroup_subgroups = 32;
  caps.subgroup_shuffle = caps.subgroup_arithmetic = true;
  caps.cooperative_matrix = true;
  vk::CooperativeMatrixShape frag;
  frag.m = frag.n = frag.k = 16;
  frag.a = frag.b = VK_COMPONENT_TYPE_FLOAT16_KHR;
  frag.c = frag.result = VK_COMPONENT_TYPE_FLOAT32_KHR;
  frag.scope = VK_SCOPE_SUBGROUP_KHR;
  caps.cooperative_matrix_shapes = {frag};
  caps.max_storage_buffer_range = caps.max_memory_allocation_size = 4ull << 30;
  caps.min_storage_buffer_offset_alignment = caps.min_texel_buffer_offset_alignment = 16;
  caps.max_texel_buffer_elements = 1ull << 27;
  caps.max_compute_shared_memory = 48 * 1024;
  caps.max_workgroup_invocations = 1024;
  caps.max_workgroup_count[0] = 2147483647, caps.max_workgroup_count[1] = caps.max_workgroup_count[2] = 65535;
  ops::ScopedTuningOverride t("gpu-coopmat,conv_shifted_gemm=on");
  const ops::DeviceTuning& tune = ops::device_tuning(caps);
  ASSERT_EQ(tune.conv, ops::KernelFamily::coopmat) << "the H200-like caps do not get the tensor-core entry";
  // A causal 3x3x3 conv of c channels at h x w over f frames (the decoder's frame batches), weights packed fp16.
  auto job = [](int64_t c, int64_t f, int64_t h, int64_t w) {
    ops::conv::ConvJob j;
    j.cin = j.cout = c, j.frames = j.frames_out = f, j.h = j.ho = h, j.w = j.wo = w;
    j.kt = j.kh = j.kw = 3, j.pad_top = j.pad_left = 1, j.prefix = 2;
    j.ys_w = 1, j.ys_h = w, j.ys_f = h * w, j.ys_c = f * h * w, j.ys_b = c * f * h * w;
    return j;
  };
  struct Weights {
    Tensor t;
    ops::PackedConvWeights p;
  };
  auto packed = [](int64_t c) {  // a view of the right shape and dtype; nothing is allocated or read
    Weights w;
    vk::BufferView view;
    view.size = uint64_t(c * 27 * ((c + 7) / 8 * 8)) * 2;
    w.t = Tensor::on(view, {c, 27 * ((c + 7) / 8 * 8)}, DType::f16);
    w.p = {w.t, {c, c, 3, 3, 3}};
    return w;
  };
  const ops::conv::ShiftedCall call{true, true, 4, 128ull << 20, nullptr};
  for (const auto& [c, f, h, w] : std::vector<std::array<int64_t, 4>>{
           {128, 4, 480, 720}, {128, 2, 480, 720}, {256, 4, 240, 360}, {512, 4, 60, 90}, {512, 13, 60, 90}}) {
    const Weights wt = packed(c);
    EXPECT_EQ(ops::conv::shifted_refusal(caps, tune, job(c, f, h, w), wt.p, call), "")
        << c << " channels at " << h << "x" << w << ", " << f << " frames";
  }
  const Weights w16 = packed(16);
  EXPECT_NE(ops::conv::shifted_refusal(caps, tune, job(16, 4, 60, 90), w16.p, call).find("not a multiple"),
            std::string::npos);
}

}  // namespace
}  // namespace dvs
