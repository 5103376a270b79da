// The tensor-core convolution's repacked input in fp16 (DeviceTuning::conv_activations_fp16: conv_pack_input.comp's
// OUT_F16, conv_coopmat.comp's X_F16). The kernel rounds an f32 chunk to fp16 as it loads it; packed in fp16 it reads
// the same values, so every convolution must give the same bits either way: every conv path of the VAE (causal
// 3x3x3 with and without a cache, 3x3, stride-2 downsample, 1x1, the fused x2 upsample), at channel counts that are
// not a multiple of 4 (5, 37) and one whose steps are whole taps (64), whole and under the limits that split the
// repack (texels=256: x read per channel, so a dispatch merges its channels into groups of 4 others wrote) and the
// call (binding=4KiB: rows and columns). Runs the tensor-core kernel where the device has one (the
// tensor-core pass), else its fp32 twin, which shares the loads. By-value correctness of the family against a
// plain-C++ reference is test_conv_families.cpp's (which runs with the default, fp16, on).
#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "support/conv_kernel_test.hpp"
#include "support/stored_values.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv.hpp"
#include "vk/pipeline.hpp"

namespace dvs {
namespace {

using test::random_stored;

class HalfInputConvOps : public test::ConvKernelTest {
 protected:
  // y of every conv path on a [1, cin, 5, 13, W] input, one vector each, under `limits` (nullptr: none).
  std::vector<std::vector<uint32_t>> all_convs(int64_t cin, const char* limits, int64_t W = 11) {
    vk::Context& c = ctx();
    const int64_t cout = 7, F = 5, H = 13;
    const Tensor x = random_stored(c, {1, cin, F, H, W}, 1, 1.f, DType::f32);
    const Tensor cache = random_stored(c, {1, cin, 2, H, W}, 2, 1.f, DType::f32);
    const Tensor w3 = random_stored(c, {cout, cin, 3, 3, 3}, 3, 0.2f, DType::bf16);
    const Tensor w2 = random_stored(c, {cout, cin, 3, 3}, 4, 0.2f, DType::bf16);
    const Tensor w1 = random_stored(c, {cout, cin, 1, 1, 1}, 5, 0.4f, DType::f32);
    const Tensor b = random_stored(c, {cout}, 6, 0.5f, DType::bf16);
    return run_paths(test::vae_conv_paths(x, cache, w3, w2, w1, b), limits);
  }
  // Whether the transposing repack's pipeline exists for fp16 (x16) or f32 output.
  bool tiled_repack_made(bool x16) {
    bool found = false;
    ctx().pipelines().for_each([&](const vk::Pipeline& pl) {
      found = found || (pl.name == "nn/conv_pack_input_tiled" && pl.spec.size() == 1 && pl.spec[0] == (x16 ? 1u : 0u));
    });
    return found;
  }
};

// A layout no other test uses (2 x 1 subgroups of 1 x 2 fragments, K 16) makes the kernel's pipelines this test's own.
TEST_F(HalfInputConvOps, SameBitsAsTheFloatRepackOnEveryPathAndSplit) {
  // (An override replaces the one in force: each run names the layout too.)
  const std::string layout = std::string(twin_ ? "" : "conv=coopmat,") + "conv_coopmat=2x1x1x2x16";
  const std::string gemm = gemm_name();
  // Whether this test's layout of the kernel was created reading an fp16 (x16) or an f32 chunk.
  auto ran = [&](bool x16) {
    bool found = false;
    ctx().pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name == gemm && pl.spec.size() == 15 && pl.spec[1] == 2 && pl.spec[2] == 1 && pl.spec[3] == 1 &&
          pl.spec[4] == 2 && pl.spec[5] == 16 && pl.spec[12] == (x16 ? 1u : 0u))
        found = true;
    });
    return found;
  };
  ASSERT_FALSE(ran(true) || ran(false));
  // binding=4KiB only at 5 channels: at 37 it would cut the f32 repack into input-channel chunks (27 x 40 x 4 B a
  // pixel) but not the fp16 one (half that), and chunks add partial sums in another order.
  const std::pair<int64_t, const char*> runs[] = {{5, nullptr},  {5, "texels=256"},  {5, "binding=4KiB"},
                                                  {37, nullptr}, {37, "texels=256"}, {64, nullptr}};
  for (const auto& [cin, limits] : runs) {
      const std::string where = "Cin " + std::to_string(cin) + (limits ? std::string(" under ") + limits : "");
      expect_same_bits(layout + ",conv_activations_fp16=on", layout + ",conv_activations_fp16=off",
                       [&] { return all_convs(cin, limits); }, where);
    }
  // The f16 runs read an fp16 chunk (which an f32 repack would have turned to garbage), the f32 runs an f32 one.
  EXPECT_TRUE(ran(true)) << "no " << gemm << " read an fp16 chunk";
  EXPECT_TRUE(ran(false)) << "no " << gemm << " read an f32 chunk";
}

// The repack's invocation order (DeviceTuning::conv_pack_pixel_major: neighbouring invocations on neighbouring pixels
// instead of neighbouring channel groups) writes the same values to the same places: every conv path gives the same
// bits either way, whole and under the texel limit that splits the repack into channel groups (each dispatch a vec4
// range that starts past 0, some merging their channels into vec4s others wrote) and frames.
TEST_F(HalfInputConvOps, PixelMajorRepackSameBits) {
  const std::string family = twin_ ? "" : "conv=coopmat,";
  auto ran = [&](bool pixel_major) {
    bool found = false;
    ctx().pipelines().for_each([&](const vk::Pipeline& pl) {
      found = found || (pl.name == "nn/conv_pack_input" && pl.spec.size() == 2 && pl.spec[1] == (pixel_major ? 1u : 0u));
    });
    return found;
  };
  for (const auto& [cin, limits] : {std::pair<int64_t, const char*>{5, nullptr}, {37, "texels=256"}, {64, nullptr}}) {
    expect_same_bits(family + "conv_pack_pixel_major=on", family + "conv_pack_pixel_major=off",
                     [&] { return all_convs(cin, limits); },
                     "Cin " + std::to_string(cin) + (limits ? std::string(" under ") + limits : ""));
  }
  EXPECT_TRUE(ran(true));
  EXPECT_TRUE(ran(false));
}

// The repack transposed through shared memory (DeviceTuning::conv_pack_tiled, conv_pack_input_tiled.comp: tiles of 32
// channels x 64 columns of a packed row) gives every conv path the same bits as the invocation-per-vec4 repack:
// channel counts with a partial channel tile (5, 37: also a partial vec4, zero channels up to 8) and whole ones (64),
// rows of one and of two column tiles (11 and 67 columns, the second tile partial), whole and under texels=256 (a
// channel per dispatch: the dispatches that merge channels into vec4s others wrote run the other kernel), fp16 and
// f32 packed chunks. Byte for byte, column chunks and the padded grids included: test_conv_repack.cpp.
TEST_F(HalfInputConvOps, TiledRepackSameBits) {
  const std::string family = twin_ ? "" : "conv=coopmat,";
  // Nothing else makes the f32 form (the shifted-GEMM convolution packs fp16): this test must make it.
  ASSERT_FALSE(tiled_repack_made(false));
  struct Run {
    int64_t cin;
    const char* limits;
    bool wide;        // 67 columns (else 11)
    const char* f16;  // conv_activations_fp16
  };
  // (texels=256 holds less than the rows of one channel that a 67-column call must repack at once.)
  const Run runs[] = {{5, nullptr, false, "on"},  {37, "texels=256", false, "on"}, {64, nullptr, false, "on"},
                      {5, nullptr, true, "on"},  {5, nullptr, true, "off"}};
  for (const Run& r : runs) {
    const std::string base = family + "conv_activations_fp16=" + r.f16 + ",conv_pack_tiled=";
    const std::string where = "Cin " + std::to_string(r.cin) + (r.limits ? std::string(" under ") + r.limits : "") +
                              ", " + (r.wide ? "67" : "11") + " columns, fp16 chunk " + r.f16;
    expect_same_bits(base + "on", base + "off",
                     [&] { return all_convs(r.cin, r.limits, r.wide ? 67 : 11); }, where);
  }
  EXPECT_TRUE(tiled_repack_made(true));
  EXPECT_TRUE(tiled_repack_made(false));
}

}  // namespace
}  // namespace dvs
