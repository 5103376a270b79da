// Which convolution calls the coopmat2 kernel (nn/conv_coopmat2.comp) takes (ops::conv_coopmat2_refusal) on a device
// with VK_NV_cooperative_matrix2's workgroup scope and tensor addressing (the H200's facts, support/coopmat2_caps.hpp),
// and the per-chunk conditions (ConvCoopmat2::takes, groups_x): each condition turned off alone is refused, with its
// reason. Its results by value: ConvFamilies.Coopmat2EveryStrideOneVariant on a device that has it.
#include <gtest/gtest.h>

#include <algorithm>

#include "support/coopmat2_caps.hpp"
#include "tensor/ops_conv_coopmat2.hpp"
#include "vk/shader_registry.hpp"

namespace dvs {
namespace {

ops::DeviceTuning on() {
  ops::DeviceTuning t;
  t.conv_coopmat2 = true;
  return t;
}

// A VAE convolution as the decoder's 512-channel ones: 60x90 frames, channels-first y of 4 frames.
ops::ConvCall vae_call() {
  ops::ConvCall c;
  c.coopmat = c.x_f16 = true;
  c.cp = 512, c.stride = 1, c.ho = 60, c.wo = 90;
  c.ys_w = 1, c.ys_h = 90, c.ys_c = 4 * 60 * 90;
  c.weight_code = 1, c.bias_code = 2;
  return c;
}

TEST(ConvCoopmat2Choice, ShaderEmbedded) {
  const std::vector<std::string> names = vk::shader_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "nn/conv_coopmat2"), names.end());
}

TEST(ConvCoopmat2Choice, TakesTheVaeConvolutions) {
  EXPECT_EQ(ops::conv_coopmat2_refusal(test::h200_like(), on(), vae_call()), "");
  ops::ConvCall c = vae_call();
  c.cp = 128, c.ho = 480, c.wo = 720, c.ys_h = 720, c.ys_c = 4 * 480 * 720;
  EXPECT_EQ(ops::conv_coopmat2_refusal(test::h200_like(), on(), c), "");
}

TEST(ConvCoopmat2Choice, RefusesEachConditionAlone) {
  const vk::DeviceCaps caps = test::h200_like();
  EXPECT_NE(ops::conv_coopmat2_refusal(caps, ops::DeviceTuning{}, vae_call()), "");  // off by default
  auto refused = [&](auto change) {
    ops::ConvCall c = vae_call();
    ops::DeviceTuning t = on();
    vk::DeviceCaps d = caps;
    change(c, t, d);
    return ops::conv_coopmat2_refusal(d, t, c);
  };
  using C = ops::ConvCall;
  using T = ops::DeviceTuning;
  using D = vk::DeviceCaps;
  EXPECT_NE(refused([](C& c, T&, D&) { c.coopmat = false; }), "");  // the twin or another family
  EXPECT_NE(refused([](C& c, T&, D&) { c.x_f16 = false; }), "");
  EXPECT_NE(refused([](C& c, T&, D&) { c.weight_code = 2; }), "");  // bf16 weights
  EXPECT_NE(refused([](C& c, T&, D&) { c.weight_code = 0; }), "");
  EXPECT_NE(refused([](C& c, T&, D&) { c.stride = 2; }), "");
  EXPECT_NE(refused([](C& c, T&, D&) { c.cp = 520; }), "");  // not a multiple of K 32
  EXPECT_NE(refused([](C& c, T&, D&) { c.ys_w = 512, c.ys_h = 90 * 512, c.ys_c = 1; }), "");  // channels-last y
  EXPECT_NE(refused([](C& c, T&, D&) { c.ys_h = 80; }), "");   // rows shorter than the chunk's columns
  EXPECT_NE(refused([](C& c, T&, D&) { c.ys_c = 90 * 59; }), "");  // channels overlapping rows
  EXPECT_NE(refused([](C&, T&, D& d) { d.cooperative_matrix2_gemm = false; }), "");
  EXPECT_NE(refused([](C&, T& t, D&) { t.conv_coopmat2_tile = {3, 16, 128, 32, 256}; }), "");  // 48 rows: no shape
  EXPECT_EQ(refused([](C&, T& t, D&) { t.conv_coopmat2_tile = {2, 64, 128, 32, 256}; }), "");
  EXPECT_EQ(refused([](C&, T& t, D&) { t.conv_coopmat2_tile = {2, 32, 64, 16, 64}; }), "");
}

TEST(ConvCoopmat2Choice, ChunksNeedAlignedBasesAndAGrid) {
  ops::ConvCoopmat2 k;
  EXPECT_FALSE(k.takes({0, 0, 0}, 5400, 1, 60, 90));  // no pipeline
  static const char fake = 0;
  k.pipe = reinterpret_cast<const vk::Pipeline*>(&fake);
  k.rows = 4, k.cols = 32, k.n = 128, k.max_groups_x = 1000;
  EXPECT_EQ(k.groups_x(2, 60, 90), 2u * 15u * 3u);
  EXPECT_EQ(k.groups_x(1, 61, 97), 16u * 4u);
  EXPECT_EQ(k.groups_x(40, 60, 90), 0u);  // 1800 workgroups: over the device's 1000
  EXPECT_TRUE(k.takes({0, 256, 5400 * 4 * 8}, 5400, 4, 60, 90));
  EXPECT_FALSE(k.takes({8, 256, 0}, 5400, 4, 60, 90));   // the packed input's binding
  EXPECT_FALSE(k.takes({0, 2, 0}, 5400, 4, 60, 90));     // the weights'
  EXPECT_FALSE(k.takes({0, 0, 4 * 90}, 5400, 4, 60, 90));  // y's first element: row 1 of 90 columns
  EXPECT_FALSE(k.takes({0, 0, 0}, 63, 4, 7, 9));         // frames of 63 pixels: the second frame unaligned
  EXPECT_TRUE(k.takes({0, 0, 0}, 63, 1, 7, 9));          // one frame
  EXPECT_FALSE(k.takes({0, 0, 0}, 5400, 40, 60, 90));    // the grid
}

}  // namespace
}  // namespace dvs
