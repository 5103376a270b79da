// PointCloudScene into and from the application's device memory (issue 22): renders into the application's RGBA8 and
// R32 images and its buffers, read back by the application in its own submission that waits for dvs's ticket on
// the timeline (no host wait in between), equal byte for byte to the host-memory render; two renders back to back
// without a host wait; images left in the layout asked for (the validation layer tracks layouts: a wrong one is an
// error); a scene built from device buffers equal bit for bit to the host-built one; refusals naming what is wrong.
// Everything runs on a device the test owns, under the validation layer with synchronization validation, across
// submissions too (the first test proves that check is live by making a hazard of its own). Sizes are odd (37×53).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "dvs/context.hpp"
#include "dvs/error.hpp"
#include "dvs/scene.hpp"
#include "support/app_device.hpp"
#include "support/expect_error.hpp"

namespace dvs {
namespace {

using test::AppDevice;

constexpr int H = 37, W = 53;
constexpr size_t kPixels = size_t(H) * W;

ContextOptions no_disk_cache() {
  ContextOptions o;
  o.pipeline_cache_file = "-";
  return o;
}

std::vector<uint8_t> random_rgb8(uint32_t seed) {
  std::mt19937 g(seed);
  std::vector<uint8_t> v(kPixels * 3);
  for (auto& x : v) x = uint8_t(g() & 255);
  return v;
}

// Disparity with structure (a slope plus noise), as a depth model gives it; or metric depth around 2.
std::vector<float> random_depth(uint32_t seed, float base) {
  std::mt19937 g(seed);
  std::uniform_real_distribution<float> u(0.f, 0.2f);
  std::vector<float> v(kPixels);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) v[size_t(y) * W + x] = base + 0.5f * float(x) / float(W) + u(g);
  return v;
}

// A camera moved right and forward and turned a little: holes and overlaps, so a wrong copy shows.
Pose moved(double dx, double yaw) {
  Pose p;
  const double c = std::cos(yaw), s = std::sin(yaw);
  p.m = {c, 0, s, -dx, 0, 1, 0, 0, -s, 0, c, -0.1, 0, 0, 0, 1};
  return p;
}

struct HostRender {
  std::vector<uint8_t> rgba;
  std::vector<float> mask;
};

HostRender render_on_host(PointCloudScene& scene, const Pose& pose) {
  HostRender r{std::vector<uint8_t>(kPixels * 4), std::vector<float>(kPixels)};
  scene.render(pose, HostView{r.rgba.data(), ElementType::u8, {H, W, 4}}, HostView{r.mask.data(), ElementType::f32, {H, W}});
  return r;
}

DeviceImageView image_view(const AppDevice::Image& i, VkImageLayout layout, VkImageLayout final_layout) {
  DeviceImageView v;
  v.image = i.image;
  v.format = i.format;
  v.width = i.width;
  v.height = i.height;
  v.layout = layout;
  v.final_layout = final_layout;
  return v;
}

constexpr VkImageUsageFlags kImageUsage =
    VK_IMAGE_USAGE_TRANSFER_DST_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_SAMPLED_BIT;

// The application, dvs's context on its device and a scene of a random frame (u8) and disparity.
class SceneDeviceMemoryTest : public ::testing::Test {
 protected:
  SceneDeviceMemoryTest()
      : ctx(app.host(), no_disk_cache()),
        frame(random_rgb8(5)),
        disparity(random_depth(6, 0.3f)),
        K(CameraIntrinsics::dvs_default(W, H)),
        scene(ctx, HostView{frame.data(), ElementType::u8, {H, W, 3}}, HostView{disparity.data(), ElementType::f32, {H, W}},
              K) {}
  void TearDown() override {
    EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s), first: " << app.first_message();
  }

  AppDevice::Image& rgba_image() { return app.image(VK_FORMAT_R8G8B8A8_UNORM, W, H, kImageUsage); }
  AppDevice::Image& mask_image() { return app.image(VK_FORMAT_R32_SFLOAT, W, H, kImageUsage); }

  AppDevice app;
  Context ctx;
  std::vector<uint8_t> frame;
  std::vector<float> disparity;
  CameraIntrinsics K;
  PointCloudScene scene;
};

TEST(SceneDeviceMemorySyncValidation, IsLiveAcrossSubmissions) {
  // Two of the application's own submissions write one buffer with nothing ordering the second after the first
  // (no barrier, no semaphore, no host wait between them): the layer must call it a hazard, or the silence of the
  // tests below proves nothing about the barriers between dvs's submissions and the application's.
  AppDevice app;
  AppDevice::Buffer& b = app.buffer(256);
  app.submit([&](VkCommandBuffer cmd) { vkCmdFillBuffer(cmd, b.buffer, 0, 256, 1u); }, {}, false);
  app.submit([&](VkCommandBuffer cmd) { vkCmdFillBuffer(cmd, b.buffer, 0, 256, 2u); }, {}, false);
  vkQueueWaitIdle(app.queue);
  ASSERT_FALSE(app.messages.empty()) << "synchronization validation across submissions is not running";
  EXPECT_NE(app.first_message().find("SYNC-HAZARD-WRITE-AFTER-WRITE"), std::string::npos) << app.first_message();
}

TEST_F(SceneDeviceMemoryTest, ImagesReadBackByTheApplicationEqualTheHostRender) {
  AppDevice::Image& image = rgba_image();
  AppDevice::Image& mask = mask_image();
  AppDevice::Buffer& image_back = app.buffer(kPixels * 4);
  AppDevice::Buffer& mask_back = app.buffer(kPixels * 4);
  const Pose pose = moved(0.05, 0.03);
  const uint64_t before = ctx.submitted_value();
  const uint64_t ticket = scene.render(pose, image_view(image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL),
                                       image_view(mask, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL));
  EXPECT_GT(ticket, before);
  EXPECT_EQ(ticket, ctx.submitted_value());
  app.submit(
      [&](VkCommandBuffer cmd) {
        AppDevice::record_image_readback(cmd, image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, image_back.buffer);
        AppDevice::record_image_readback(cmd, mask, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, mask_back.buffer);
      },
      {{ctx.timeline(), ticket}});
  const HostRender want = render_on_host(scene, pose);
  EXPECT_EQ(std::memcmp(image_back.data, want.rgba.data(), want.rgba.size()), 0) << "the RGBA8 image differs";
  EXPECT_EQ(std::memcmp(mask_back.data, want.mask.data(), want.mask.size() * 4), 0) << "the mask image differs";
  size_t visible = 0;
  for (float m : want.mask) visible += m == 1.0f;
  EXPECT_GT(visible, kPixels / 2);
  EXPECT_LT(visible, kPixels);  // the moved camera shows holes: an all-visible copy would not test the mask
}

TEST_F(SceneDeviceMemoryTest, AnRGBA8MaskImageIsWhiteWhereVisibleAndBlackElsewhere) {
  // The display form of the mask (what a window blits as it is): opaque white where the f32 mask is 1, opaque
  // black where it is 0, checked pixel by pixel against the host render's mask.
  AppDevice::Image& image = rgba_image();
  AppDevice::Image& mask = rgba_image();
  AppDevice::Buffer& mask_back = app.buffer(kPixels * 4);
  const Pose pose = moved(-0.04, 0.02);
  const VkImageLayout U = VK_IMAGE_LAYOUT_UNDEFINED, T = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
  const uint64_t ticket = scene.render(pose, image_view(image, U, T), image_view(mask, U, T));
  app.submit([&](VkCommandBuffer cmd) { AppDevice::record_image_readback(cmd, mask, T, mask_back.buffer); },
             {{ctx.timeline(), ticket}});
  const HostRender want = render_on_host(scene, pose);
  const auto* got = static_cast<const uint8_t*>(mask_back.data);
  size_t wrong = 0, visible = 0;
  for (size_t i = 0; i < kPixels; ++i) {
    const uint8_t v = want.mask[i] > 0.0f ? 255 : 0;
    visible += v == 255;
    wrong += !(got[4 * i] == v && got[4 * i + 1] == v && got[4 * i + 2] == v && got[4 * i + 3] == 255);
  }
  EXPECT_EQ(wrong, 0u) << "pixels of the RGBA8 mask differ from the host mask";
  EXPECT_GT(visible, 0u);
  EXPECT_LT(visible, kPixels);  // holes and visible pixels both present
}

TEST_F(SceneDeviceMemoryTest, BuffersReadBackByTheApplicationEqualTheHostRender) {
  AppDevice::Buffer& image = app.buffer(kPixels * 4);
  AppDevice::Buffer& mask = app.buffer(kPixels * 4);
  AppDevice::Buffer& image_back = app.buffer(kPixels * 4);
  AppDevice::Buffer& mask_back = app.buffer(kPixels * 4);
  const Pose pose = moved(-0.04, -0.02);
  const uint64_t ticket = scene.render(pose, DeviceBufferView{image.buffer, 0, ElementType::u8, {H, W, 4}},
                                       DeviceBufferView{mask.buffer, 0, ElementType::f32, {H, W}});
  app.submit(
      [&](VkCommandBuffer cmd) {
        const VkBufferCopy all{0, 0, kPixels * 4};
        vkCmdCopyBuffer(cmd, image.buffer, image_back.buffer, 1, &all);
        vkCmdCopyBuffer(cmd, mask.buffer, mask_back.buffer, 1, &all);
        VkMemoryBarrier to_host{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
        to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
        to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, nullptr,
                             0, nullptr);
      },
      {{ctx.timeline(), ticket}});
  const HostRender want = render_on_host(scene, pose);
  EXPECT_EQ(std::memcmp(image_back.data, want.rgba.data(), want.rgba.size()), 0) << "the RGBA8 buffer differs";
  EXPECT_EQ(std::memcmp(mask_back.data, want.mask.data(), want.mask.size() * 4), 0) << "the mask buffer differs";
}

TEST_F(SceneDeviceMemoryTest, TwoRendersBackToBackEachKeepTheirPose) {
  AppDevice::Image& first = rgba_image();
  AppDevice::Image& second = rgba_image();
  AppDevice::Buffer& first_back = app.buffer(kPixels * 4);
  AppDevice::Buffer& second_back = app.buffer(kPixels * 4);
  const Pose a = moved(0.06, 0.0), b = moved(-0.06, 0.04);
  const uint64_t t1 = scene.render(a, image_view(first, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL));
  const uint64_t t2 = scene.render(b, image_view(second, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL));
  EXPECT_GT(t2, t1);
  app.submit(
      [&](VkCommandBuffer cmd) {
        AppDevice::record_image_readback(cmd, first, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, first_back.buffer);
        AppDevice::record_image_readback(cmd, second, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, second_back.buffer);
      },
      {{ctx.timeline(), t2}});
  const HostRender want_a = render_on_host(scene, a), want_b = render_on_host(scene, b);
  ASSERT_NE(want_a.rgba, want_b.rgba) << "the two poses must give different images for this test to mean anything";
  EXPECT_EQ(std::memcmp(first_back.data, want_a.rgba.data(), want_a.rgba.size()), 0) << "the first render differs";
  EXPECT_EQ(std::memcmp(second_back.data, want_b.rgba.data(), want_b.rgba.size()), 0) << "the second render differs";
}

TEST_F(SceneDeviceMemoryTest, ImagesAreLeftInTheFinalLayoutAskedFor) {
  AppDevice::Image& image = rgba_image();
  AppDevice::Buffer& back = app.buffer(kPixels * 4);
  const Pose pose = moved(0.02, 0.01);
  // Left for sampling; the application's next use starts from SHADER_READ_ONLY_OPTIMAL (the layer checks that).
  uint64_t t = scene.render(pose, image_view(image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL));
  app.submit([&](VkCommandBuffer cmd) {
    AppDevice::record_image_readback(cmd, image, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, back.buffer);
  }, {{ctx.timeline(), t}});
  EXPECT_TRUE(app.messages.empty()) << app.first_message();
  // The next render starts from where the application left it (TRANSFER_SRC_OPTIMAL), keeping its contents.
  t = scene.render(pose, image_view(image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_GENERAL));
  app.submit([&](VkCommandBuffer cmd) {
    AppDevice::record_image_readback(cmd, image, VK_IMAGE_LAYOUT_GENERAL, back.buffer);
  }, {{ctx.timeline(), t}});
  EXPECT_TRUE(app.messages.empty()) << app.first_message();
  EXPECT_EQ(std::memcmp(back.data, render_on_host(scene, pose).rgba.data(), kPixels * 4), 0);

  // The layer does track it: the application claiming another layout than dvs left is an error.
  t = scene.render(pose, image_view(image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL));
  app.submit([&](VkCommandBuffer cmd) {
    AppDevice::record_image_readback(cmd, image, VK_IMAGE_LAYOUT_GENERAL, back.buffer);
  }, {{ctx.timeline(), t}});
  ASSERT_FALSE(app.messages.empty()) << "a wrong layout went unnoticed: the layout checks above prove nothing";
  EXPECT_NE(app.first_message().find("layout"), std::string::npos) << app.first_message();
  app.messages.clear();
}

TEST_F(SceneDeviceMemoryTest, SceneFromDeviceBuffersRendersBitIdenticallyToTheHostOne) {
  const std::vector<float> metric = random_depth(8, 1.5f);
  std::vector<float> planar(kPixels * 3);
  std::mt19937 g(9);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  for (auto& x : planar) x = u(g);
  struct Case {
    const char* name;
    ElementType frame_type;
    std::vector<int64_t> frame_shape;
    const void* frame_data;
    size_t frame_bytes;
    const std::vector<float>* depth;
    bool disparity;
  };
  const Case cases[] = {
      {"u8 frame, disparity", ElementType::u8, {H, W, 3}, frame.data(), frame.size(), &disparity, true},
      {"f32 frame, metric depth", ElementType::f32, {3, H, W}, planar.data(), planar.size() * 4, &metric, false},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    AppDevice::Buffer& f = app.buffer(c.frame_bytes + 4);
    AppDevice::Buffer& d = app.buffer(kPixels * 4 + 4);
    // At an offset, so a copy that ignores it shows.
    std::memcpy(static_cast<uint8_t*>(f.data) + 4, c.frame_data, c.frame_bytes);
    std::memcpy(static_cast<uint8_t*>(d.data) + 4, c.depth->data(), kPixels * 4);
    SceneOptions o;
    o.depth_is_disparity = c.disparity;
    PointCloudScene from_device(ctx, DeviceBufferView{f.buffer, 4, c.frame_type, c.frame_shape},
                                DeviceBufferView{d.buffer, 4, ElementType::f32, {H, W}}, K, o);
    PointCloudScene from_host(ctx, HostView{const_cast<void*>(c.frame_data), c.frame_type, c.frame_shape},
                              HostView{const_cast<float*>(c.depth->data()), ElementType::f32, {H, W}}, K, o);
    EXPECT_EQ(from_device.centre_depth(), from_host.centre_depth());
    for (const Pose& pose : {Pose{}, moved(0.07, -0.03)}) {
      std::vector<float> got(kPixels * 3), want(kPixels * 3), got_mask(kPixels), want_mask(kPixels);
      from_device.render(pose, HostView{got.data(), ElementType::f32, {3, H, W}}, HostView{got_mask.data(), ElementType::f32, {H, W}});
      from_host.render(pose, HostView{want.data(), ElementType::f32, {3, H, W}}, HostView{want_mask.data(), ElementType::f32, {H, W}});
      EXPECT_EQ(std::memcmp(got.data(), want.data(), got.size() * 4), 0) << "the render differs";
      EXPECT_EQ(std::memcmp(got_mask.data(), want_mask.data(), got_mask.size() * 4), 0) << "the mask differs";
    }
  }
}

TEST_F(SceneDeviceMemoryTest, WrongImagesAreRefusedSayingWhatIsWrong) {
  AppDevice::Image& rgba = rgba_image();
  AppDevice::Image& srgb = app.image(VK_FORMAT_R8G8B8A8_SRGB, W, H, kImageUsage);
  AppDevice::Image& small = app.image(VK_FORMAT_R8G8B8A8_UNORM, W - 1, H, kImageUsage);
  const Pose pose;
  const VkImageLayout U = VK_IMAGE_LAYOUT_UNDEFINED, S = VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL;
  test::expect_error([&] { scene.render(pose, image_view(srgb, U, S)); }, {"PointCloudScene's image", "sRGB", "R8G8B8A8_UNORM"});
  test::expect_error([&] { scene.render(pose, image_view(small, U, S)); }, {"PointCloudScene's image", "wrong size", "53x37"});
  test::expect_error([&] { scene.render(pose, DeviceImageView{}); }, {"PointCloudScene's image", "VK_NULL_HANDLE"});
  test::expect_error([&] { scene.render(pose, image_view(rgba, U, U)); }, {"PointCloudScene's image", "final_layout"});
  AppDevice::Image& r8 = app.image(VK_FORMAT_R8_UNORM, W, H, kImageUsage);
  test::expect_error([&] { scene.render(pose, image_view(rgba, U, S), image_view(r8, U, S)); },
                     {"PointCloudScene's mask", "VK_FORMAT_R32_SFLOAT", "VK_FORMAT_R8G8B8A8_UNORM"});
  // Nothing was submitted by a refused call: the next render still works.
  const uint64_t before = ctx.submitted_value();
  EXPECT_GT(scene.render(pose, image_view(rgba, U, S)), before);
  EXPECT_TRUE(ctx.wait(ctx.submitted_value()));
}

}  // namespace
}  // namespace dvs
