// The tensor-core convolution's 16-byte gathers (DeviceTuning::conv_coopmat_vector_loads: conv_coopmat.comp's VEC8):
// 8 channels per load from the fp16 repack, each pixel's taps worked out once. They stage the very values the 4-channel
// gather stages, in the same places, so every convolution must give the same bits with them on and off: every conv
// path of the VAE (causal 3x3x3 with and without a cache, 3x3, the stride-2 downsample, 1x1, the fused x2 upsample,
// whose taps depend on each pixel's parity) on odd frame, row and column counts, with bf16 weights (converted as
// staged) and fp16 weights packed at load (staged as they are), at two layouts (one and several gather passes over a
// tile), whole and under limits that split the call into
// row and column chunks (a chunk's first source row and column not 0, its borders inside the image). Runs the
// tensor-core kernel where the device has one (the tensor-core pass), else its fp32 twin, which shares the loads.
// By-value correctness against a plain-C++ reference is test_conv_families.cpp's (its cases with 32 and 64 input
// channels take the 16-byte gathers under the default tuning).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "support/conv_kernel_test.hpp"
#include "support/stored_values.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv.hpp"
#include "tensor/ops_conv_weights.hpp"
#include "vk/pipeline.hpp"

namespace dvs {
namespace {

using test::random_stored;

class VectorGatherConvOps : public test::ConvKernelTest {
 protected:
  // y of every conv path on a [1, cin, 3, 11, 13] input with 19 output channels, one vector each, under `limits`
  // (nullptr: none); weights bf16 as stored or packed in fp16 (`packed`).
  std::vector<std::vector<uint32_t>> all_convs(int64_t cin, bool packed, const char* limits) {
    vk::Context& c = ctx();
    const int64_t cout = 19, F = 3, H = 11, W = 13;
    const Tensor x = random_stored(c, {1, cin, F, H, W}, 1, 1.f, DType::f32);
    const Tensor cache = random_stored(c, {1, cin, 2, H, W}, 2, 1.f, DType::f32);
    const Tensor w3 = random_stored(c, {cout, cin, 3, 3, 3}, 3, 0.2f, packed ? DType::f16 : DType::bf16);
    const Tensor w2 = random_stored(c, {cout, cin, 3, 3}, 4, 0.2f, packed ? DType::f16 : DType::bf16);
    const Tensor w1 = random_stored(c, {cout, cin, 1, 1, 1}, 5, 0.4f, packed ? DType::f16 : DType::bf16);
    const Tensor b = random_stored(c, {cout}, 6, 0.5f, DType::bf16);
    std::vector<ops::PackedConvWeights> p;
    if (packed)
      for (const Tensor* w : {&w3, &w2, &w1}) p.push_back(ops::packed_conv_weights_now(c, *w, "test weights"));
    const auto paths = packed ? test::vae_conv_paths(x, cache, p[0], p[1], p[2], b)
                              : test::vae_conv_paths(x, cache, w3, w2, w1, b);
    return run_paths(paths, limits);
  }
  // Whether a conv kernel of layout `l` (sg_m, sg_n, fm, fn, k) was created with the 16-byte gathers on (`vec8`) or off.
  bool ran(const std::array<uint32_t, 5>& l, bool vec8) {
    const std::string gemm = gemm_name();
    bool found = false;
    ctx().pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name == gemm && pl.spec.size() == 15 && std::equal(l.begin(), l.end(), pl.spec.begin() + 1) &&
          pl.spec[14] == (vec8 ? 1u : 0u))
        found = true;
    });
    return found;
  }
};

// Layouts no other test uses, so the pipelines this test finds are its own: 1 x 2 subgroups of 2 x 1 fragments, K 16
// (one gather pass over each tile at 32 lanes, two at 8), and 2 x 1 subgroups of 1 x 2 fragments, K 32 (two passes
// at 32 lanes, four at 8).
TEST_F(VectorGatherConvOps, SameBitsAsTheFourChannelGatherOnEveryPathAndSplit) {
  struct Run {
    const char* layout;
    std::array<uint32_t, 5> l;
    int64_t cin;
    bool packed;
    const char* limits;
  };
  // The first run of each layout proves that both gathers ran (no pipeline of it exists before).
  const Run runs[] = {
      {"conv_coopmat=1x2x2x1x16", {1, 2, 2, 1, 16}, 32, false, nullptr},
      {"conv_coopmat=1x2x2x1x16", {1, 2, 2, 1, 16}, 48, true, nullptr},
      {"conv_coopmat=1x2x2x1x16", {1, 2, 2, 1, 16}, 32, false, "binding=16KiB"},  // rows and columns of a frame per call
      {"conv_coopmat=2x1x1x2x32", {2, 1, 1, 2, 32}, 64, true, nullptr},
      {"conv_coopmat=2x1x1x2x32", {2, 1, 1, 2, 32}, 32, false, "binding=8KiB"},
  };
  std::set<std::string> seen;
  for (const Run& r : runs) {
    if (seen.insert(r.layout).second) {
      ASSERT_FALSE(ran(r.l, true) || ran(r.l, false)) << r.layout << ": another test's pipelines";
    }
    const std::string base = std::string(twin_ ? "" : "conv=coopmat,") + r.layout;
    const std::string where = std::string(r.layout) + ", Cin " + std::to_string(r.cin) +
                              (r.packed ? ", fp16 weights packed at load" : ", bf16 weights") +
                              (r.limits ? std::string(" under ") + r.limits : "");
    expect_same_bits(base + ",conv_coopmat_vector_loads=on", base + ",conv_coopmat_vector_loads=off",
                     [&] { return all_convs(r.cin, r.packed, r.limits); }, where);
    // Both kernels ran: the option is applied, and the comparison is not one kernel against itself.
    EXPECT_TRUE(ran(r.l, true)) << where << ": no 16-byte gather ran";
    EXPECT_TRUE(ran(r.l, false)) << where << ": no 4-channel gather ran";
  }
}

// Where they do not apply the kernel keeps the 4-channel gather: f32 weights, channels not a multiple of the tile's K,
// an f32 repack (at 1 x 1 subgroups of 1 x 1 fragments, K 16, which takes them otherwise), and a tile that is not
// whole gather passes (1 x 4 subgroups of 1 x 1 fragments at 32 lanes, 1 x 8 at 8: a pass is twice the tile's
// pixels). Layouts of this test's own.
TEST_F(VectorGatherConvOps, FourChannelGatherWhereTheyDoNotApply) {
  vk::Context& c = ctx();
  const std::string family = twin_ ? "" : "conv=coopmat,";
  const std::array<uint32_t, 5> fits = {1, 1, 1, 1, 16}, unfit = {1, twin_ ? 4u : 8u, 1, 1, 32};
  const std::string unfit_layout = twin_ ? "conv_coopmat=1x4x1x1x32" : "conv_coopmat=1x8x1x1x32";
  struct Run {
    int64_t cin;
    DType w;
    std::string tuning;
    std::array<uint32_t, 5> layout;
  };
  const Run runs[] = {{32, DType::bf16, "conv_coopmat=1x1x1x1x16", fits},  // applies: the layout takes them
                      {32, DType::f32, "conv_coopmat=1x1x1x1x16", fits},
                      {40, DType::bf16, "conv_coopmat=1x1x1x1x16", fits},
                      {32, DType::bf16, "conv_coopmat=1x1x1x1x16,conv_activations_fp16=off", fits},
                      {32, DType::bf16, unfit_layout, unfit}};
  for (const Run& r : runs) {
    const bool applies = &r == &runs[0];
    ops::ScopedTuningOverride t(family + r.tuning);
    const Tensor x = random_stored(c, {1, r.cin, 2, 5, 7}, 1, 1.f, DType::f32);
    const Tensor w = random_stored(c, {8, r.cin, 3, 3}, 2, 0.2f, r.w);
    const Tensor y = Tensor::empty(c, {1, 8, 2, 5, 7}, DType::f32);
    const bool before = ran(r.layout, true);
    ops::run_now(c, [&](vk::Recorder& rec) { ops::conv2d(rec, x, w, nullptr, y, ops::Conv2dParams::same3x3()); });
    const std::string what = "Cin " + std::to_string(r.cin) + ", " + dtype_name(r.w) + ", " + r.tuning;
    if (applies) {
      EXPECT_TRUE(ran(r.layout, true)) << what;
    } else {
      EXPECT_EQ(ran(r.layout, true), before) << what << ": a 16-byte gather ran";
      EXPECT_TRUE(ran(r.layout, false)) << what;
    }
  }
  EXPECT_FALSE(ran(unfit, true)) << unfit_layout;
}

}  // namespace
}  // namespace dvs
