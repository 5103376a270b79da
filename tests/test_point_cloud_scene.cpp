// dvs::PointCloudScene (dvs/scene.hpp, issue 22): the splat render as a call. A render equals `dvs render`'s of
// the same frame, depth and pose (render_clip by value, and the program's mask.npy), the pose is read row-major
// (a known translation moves a plane by the pinhole-predicted pixels), RGBA8 is the video writer's quantisation,
// and wrong views are refused naming the argument. Sizes are small and odd (37×53) so a wrong stride shows.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "dvs/context.hpp"
#include "dvs/error.hpp"
#include "dvs/scene.hpp"
#include "geometry/splat.hpp"
#include "geometry/trajectory.hpp"
#include "io/depth.hpp"
#include "io/npy.hpp"
#include "support/files.hpp"
#include "support/process.hpp"
#include "vk/context.hpp"

namespace dvs {
namespace {

constexpr int H = 37, W = 53;

std::optional<Context>& scene_context_slot() {
  static std::optional<Context> ctx;
  return ctx;
}

Context& scene_context() {
  std::optional<Context>& ctx = scene_context_slot();
  if (!ctx) {
    ContextOptions o;
    o.validation = true;
    o.pipeline_cache_file = "-";
    ctx.emplace(o);
  }
  return *ctx;
}

// Released when the tests are done, before main returns: left to the exit handlers, the context was destroyed after
// static objects the validation layer makes at first use, and under synchronization validation its release never
// returned (the program hung after its summary; support/gpu.cpp does the same for the shared vk::Context).
class ReleaseSceneContext : public ::testing::Environment {
 public:
  void TearDown() override { scene_context_slot().reset(); }
};
::testing::Environment* const kReleaseSceneContext = ::testing::AddGlobalTestEnvironment(new ReleaseSceneContext);

class PointCloudSceneTest : public ::testing::Test {
 protected:
  void SetUp() override { scene_context().internal().clear_validation_messages(); }
  void TearDown() override {
    const auto msgs = scene_context().internal().validation_messages();
    EXPECT_TRUE(msgs.empty()) << msgs.size() << " validation message(s), first: " << (msgs.empty() ? "" : msgs[0]);
  }
  Context& ctx() { return scene_context(); }
};

std::vector<uint8_t> random_rgb8(int h, int w, uint32_t seed) {
  std::mt19937 g(seed);
  std::vector<uint8_t> v(size_t(h) * w * 3);
  for (auto& x : v) x = uint8_t(g() & 255);
  return v;
}

std::vector<float> random_planar(int h, int w, uint32_t seed) {
  std::mt19937 g(seed);
  std::uniform_real_distribution<float> u(-1.f, 1.f);
  std::vector<float> v(size_t(3) * h * w);
  for (auto& x : v) x = u(g);
  return v;
}

// Disparity with structure (a slope plus noise), as a depth model gives it.
std::vector<float> random_disparity(int h, int w, uint32_t seed) {
  std::mt19937 g(seed);
  std::uniform_real_distribution<float> u(0.f, 0.2f);
  std::vector<float> v(size_t(h) * w);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) v[size_t(y) * w + x] = 0.3f + 0.5f * float(x) / float(w) + u(g);
  return v;
}

HostView view(std::vector<float>& v, std::vector<int64_t> shape) { return HostView{v.data(), ElementType::f32, shape}; }
HostView view(std::vector<uint8_t>& v, std::vector<int64_t> shape) { return HostView{v.data(), ElementType::u8, shape}; }

Pose pose_of(const glm::dmat4& T) {
  Pose p;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) p.m[size_t(r * 4 + c)] = T[c][r];
  return p;
}

// A camera f = 64 px, centre (26, 18): with power-of-two depths a fronto-parallel plane projects exactly.
CameraIntrinsics exact_camera() { return CameraIntrinsics{64, 64, 26, 18, W, H}; }

geometry::Intrinsics internal_camera(const CameraIntrinsics& k) {
  geometry::Intrinsics g;
  g.fx = k.fx, g.fy = k.fy, g.cx = k.cx, g.cy = k.cy, g.width = k.width, g.height = k.height;
  return g;
}

struct Rendered {
  std::vector<float> image = std::vector<float>(size_t(3) * H * W), mask = std::vector<float>(size_t(H) * W);
};

Rendered render(PointCloudScene& scene, const Pose& pose) {
  Rendered r;
  scene.render(pose, view(r.image, {3, H, W}), view(r.mask, {H, W}));
  return r;
}

std::vector<glm::dmat4> test_poses() {
  return {geometry::rotation_y(0.08) * geometry::translation({0.05, -0.02, 0.1}),
          geometry::rotation_x(-0.05) * geometry::translation({-0.1, 0.03, -0.05}),
          geometry::translation({0.0, 0.0, 0.3}) * geometry::rotation_y(-0.12)};
}

template <class T>
size_t differing(const std::vector<T>& a, const std::vector<T>& b) {
  size_t n = 0;
  for (size_t i = 0; i < a.size(); ++i) n += a[i] != b[i];
  return n;
}

// Every pose, soft and hard, disparity and metric depth: the scene's render and mask equal render_clip's (what
// `dvs render` runs) of the same frame and depth as a one-frame clip, bit for bit.
TEST_F(PointCloudSceneTest, RenderEqualsRenderClip) {
  std::vector<float> frame = random_planar(H, W, 1), disparity = random_disparity(H, W, 2);
  std::vector<float> metric(disparity.size());
  for (size_t i = 0; i < metric.size(); ++i) metric[i] = 1.0f / disparity[i];
  const CameraIntrinsics K = CameraIntrinsics::dvs_default(W, H);
  HostTensor rgb({1, 3, H, W}, DType::f32);
  std::copy(frame.begin(), frame.end(), rgb.as<float>());
  for (const bool hard : {false, true})
    for (const bool is_disparity : {true, false}) {
      SCOPED_TRACE(std::string(hard ? "hard" : "soft") + (is_disparity ? ", disparity" : ", metric depth"));
      std::vector<float>& d = is_disparity ? disparity : metric;
      PointCloudScene scene(ctx(), view(frame, {3, H, W}), view(d, {H, W}), K, {is_disparity, hard});
      HostTensor raw({1, H, W}, DType::f32);
      std::copy(d.begin(), d.end(), raw.as<float>());
      DepthOptions o;
      o.values = is_disparity ? DepthValues::disparity : DepthValues::depth;
      const HostTensor z = depth_from_array(raw, "depth", o);
      geometry::SplatOptions so;
      so.mode = hard ? geometry::SplatMode::hard_point : geometry::SplatMode::soft_bilinear;
      EXPECT_EQ(scene.centre_depth(), double(z.as<float>()[(H / 2) * W + W / 2]));
      EXPECT_EQ(scene.orbit_radius(), std::min(scene.centre_depth(), 5.0));  // the official radius: capped at 5
      for (const glm::dmat4& T : test_poses()) {
        const Rendered got = render(scene, pose_of(T));
        geometry::Trajectory t;
        t.transforms = {T};
        const geometry::RenderedClip want = geometry::render_clip(ctx().internal(), rgb, z, t, internal_camera(K), so);
        EXPECT_EQ(differing(got.image, std::vector<float>(want.render.as<float>(), want.render.as<float>() + 3 * H * W)), 0u);
        EXPECT_EQ(differing(got.mask, std::vector<float>(want.mask.as<float>(), want.mask.as<float>() + H * W)), 0u);
        size_t visible = 0;
        for (float m : got.mask) visible += m > 0;
        EXPECT_GT(visible, size_t(H * W / 2));  // the poses keep most of the scene in view
      }
    }
}

// At the identity pose every point lands on its own pixel: the hard splat gives the input frame back exactly,
// the soft one within its fixed-point resolution (a plane at a power-of-two depth projects exactly).
TEST_F(PointCloudSceneTest, IdentityPoseReproducesTheFrame) {
  std::vector<float> frame = random_planar(H, W, 3), disparity = random_disparity(H, W, 4);
  std::vector<float> plane(size_t(H) * W, 2.0f);
  {
    PointCloudScene scene(ctx(), view(frame, {3, H, W}), view(disparity, {H, W}), exact_camera(), {true, true});
    const Rendered r = render(scene, Pose{});
    EXPECT_EQ(differing(r.image, frame), 0u);
    EXPECT_EQ(differing(r.mask, std::vector<float>(r.mask.size(), 1.0f)), 0u);
  }
  PointCloudScene scene(ctx(), view(frame, {3, H, W}), view(plane, {H, W}), exact_camera(), {false, false});
  const Rendered r = render(scene, Pose{});
  float worst = 0;
  for (size_t i = 0; i < frame.size(); ++i) worst = std::max(worst, std::abs(r.image[i] - frame[i]));
  EXPECT_LT(worst, 1e-4f);
  EXPECT_EQ(differing(r.mask, std::vector<float>(r.mask.size(), 1.0f)), 0u);
}

// Issue 34 §2 item 8 as a library user met it: the soft splat of a random frame with disparity 0.5 + y/H (the
// scene converts it) at dvs's default camera and the identity pose gives back the frame, at the 48×80 and
// other sizes (row 0 came back up to 210 levels off while the mask said visible; test_geometry_splat_identity.cpp
// sweeps the renderer over 338 sizes).
TEST_F(PointCloudSceneTest, SoftSplatAtTheIdentityGivesBackALandscapeFrame) {
  const uint64_t binding = ctx().internal().caps().max_storage_buffer_range;  // lowered by DVS_LIMITS in that pass
  for (const auto& [h, w] : std::vector<std::pair<int, int>>{{48, 80}, {8, 8}, {16, 24}, {24, 40}, {37, 53}, {96, 160}, {45, 81}}) {
    if (uint64_t(h) * uint64_t(w) * 16 > binding) continue;  // one frame's accumulation must fit a binding
    std::vector<float> frame(size_t(3) * h * w), disparity(size_t(h) * w), image(frame.size()), mask(disparity.size());
    std::mt19937 g(9);
    std::uniform_real_distribution<float> u(-1.f, 1.f);
    for (auto& v : frame) v = u(g);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) disparity[size_t(y) * w + x] = 0.5f + float(y) / float(h);
    PointCloudScene scene(ctx(), view(frame, {3, h, w}), view(disparity, {h, w}), CameraIntrinsics::dvs_default(w, h, false),
                          {true, false});
    scene.render(Pose{}, view(image, {3, h, w}), view(mask, {h, w}));
    float worst = 0;
    for (size_t i = 0; i < frame.size(); ++i) worst = std::max(worst, std::abs(image[i] - frame[i]));
    EXPECT_LT(worst * 127.5f, 0.01f) << h << "x" << w << ": levels off the input";
    EXPECT_EQ(differing(mask, std::vector<float>(mask.size(), 1.0f)), 0u) << h << "x" << w;
  }
}

// A plane at depth 2 seen with f = 64: moving the points by t = (3·2/64, −2·2/64, 0) moves the image by (3, −2)
// pixels (u' = u + f·tx/Z). The translation is in m[3] and m[7] of the row-major pose; read column-major it
// would be the bottom row, which is refused.
TEST_F(PointCloudSceneTest, KnownTranslationShiftsAPlaneByThePinholePrediction) {
  std::vector<float> frame = random_planar(H, W, 5), plane(size_t(H) * W, 2.0f);
  PointCloudScene scene(ctx(), view(frame, {3, H, W}), view(plane, {H, W}), exact_camera(), {false, true});
  Pose p;
  p.m[3] = 3 * 2.0 / 64;
  p.m[7] = -2 * 2.0 / 64;
  const Rendered r = render(scene, p);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const int sx = x - 3, sy = y + 2;
      const bool inside = sx >= 0 && sy < H;
      ASSERT_EQ(r.mask[size_t(y) * W + x], inside ? 1.0f : 0.0f) << "pixel " << x << "," << y;
      for (int c = 0; c < 3; ++c)
        ASSERT_EQ(r.image[(size_t(c) * H + y) * W + x], inside ? frame[(size_t(c) * H + sy) * W + sx] : -1.0f)
            << "pixel " << x << "," << y << " channel " << c;
    }
}

// The transpose of a rigid transform: with a translation its bottom row is not 0 0 0 1 (refused, naming the
// row-major layout); a pure rotation's transpose is its inverse, which looks the other way (a different image).
TEST_F(PointCloudSceneTest, TransposedPoseIsRefusedOrRendersDifferently) {
  std::vector<float> frame = random_planar(H, W, 6), disparity = random_disparity(H, W, 7);
  PointCloudScene scene(ctx(), view(frame, {3, H, W}), view(disparity, {H, W}), CameraIntrinsics::dvs_default(W, H));
  const glm::dmat4 rigid = test_poses()[0];
  try {
    render(scene, pose_of(glm::transpose(rigid)));
    ADD_FAILURE() << "a transposed rigid transform was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("pose: the bottom row must be 0 0 0 1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("row-major"), std::string::npos) << e.what();
  }
  const glm::dmat4 R = geometry::rotation_y(0.1) * geometry::rotation_x(0.05);
  const Rendered a = render(scene, pose_of(R)), b = render(scene, pose_of(glm::transpose(R)));
  EXPECT_GT(differing(a.mask, b.mask) + differing(a.image, b.image), size_t(H * W / 10));
}

// RGBA8 is the f32 render quantised by the video writer's rule, computed here: round((x + 1)·127.5) clamped to
// 0..255 with halves away from zero; alpha 255 where visible, black with alpha 0 in holes. The frame holds values
// at and near the half levels, which the hard splat at the identity pose passes through unchanged (other ways of
// rounding, round() to even or floor(u + 0.5), each fail on some of them).
TEST_F(PointCloudSceneTest, Rgba8IsTheVideoWritersQuantisation) {
  std::vector<float> frame = random_planar(H, W, 8), disparity = random_disparity(H, W, 9);
  for (size_t i = 0; i < frame.size(); i += 3) {
    const float half = float((double(i % 256) + 0.5) / 127.5 - 1.0);
    frame[i] = i % 2 ? half : std::nextafter(half, -2.0f);
  }
  // (x + 1)·127.5 = 0.5 − 2⁻²⁵ exactly: level 0 by the rule, but floor(u + 0.5) would round up to 1.
  frame[1] = float(-1.0 + 65793.0 / 16777216.0);
  ASSERT_EQ((frame[1] + 1.0f) * 127.5f, 0.5f - std::ldexp(1.0f, -25));
  const auto level = [](float x) { return uint8_t(std::lround(std::clamp((x + 1.0f) * 127.5f, 0.0f, 255.0f))); };
  for (const bool hard : {true, false}) {
    PointCloudScene scene(ctx(), view(frame, {3, H, W}), view(disparity, {H, W}), CameraIntrinsics::dvs_default(W, H),
                          {true, hard});
    for (const Pose& pose : {Pose{}, pose_of(test_poses()[1])}) {
      const Rendered f = render(scene, pose);
      std::vector<uint8_t> rgba(size_t(H) * W * 4, 77), want(rgba.size(), 0);
      std::vector<float> mask(size_t(H) * W, -5);
      scene.render(pose, view(rgba, {H, W, 4}), view(mask, {H, W}));
      for (size_t i = 0; i < size_t(H) * W; ++i)
        if (f.mask[i] > 0) {
          for (size_t c = 0; c < 3; ++c) want[i * 4 + c] = level(f.image[c * H * W + i]);
          want[i * 4 + 3] = 255;
        }
      EXPECT_EQ(differing(rgba, want), 0u) << (hard ? "hard" : "soft");
      EXPECT_EQ(differing(mask, f.mask), 0u);
    }
  }
}

// A u8 [H,W,3] frame is read as a video decoder's frame: level/127.5 − 1 per channel, RGB planes.
TEST_F(PointCloudSceneTest, Rgb8FrameEqualsItsConversion) {
  std::vector<uint8_t> rgb8 = random_rgb8(H, W, 10);
  std::vector<float> planar(size_t(3) * H * W), disparity = random_disparity(H, W, 11);
  for (size_t i = 0; i < size_t(H) * W; ++i)
    for (size_t c = 0; c < 3; ++c) planar[c * H * W + i] = float(rgb8[i * 3 + c]) / 127.5f - 1.0f;
  const CameraIntrinsics K = CameraIntrinsics::dvs_default(W, H);
  PointCloudScene from_u8(ctx(), view(rgb8, {H, W, 3}), view(disparity, {H, W}), K);
  PointCloudScene from_f32(ctx(), view(planar, {3, H, W}), view(disparity, {H, W}), K);
  for (const glm::dmat4& T : test_poses()) {
    const Rendered a = render(from_u8, pose_of(T)), b = render(from_f32, pose_of(T));
    EXPECT_EQ(differing(a.image, b.image), 0u);
    EXPECT_EQ(differing(a.mask, b.mask), 0u);
  }
}

// A repeated pose skips the splat (its result is still on the device) and a destination kept replays its
// recording: alternating poses and outputs must still give each pose's own image every time.
TEST_F(PointCloudSceneTest, RepeatedAndAlternatingPosesGiveEachPosesImage) {
  std::vector<float> frame = random_planar(H, W, 18), disparity = random_disparity(H, W, 19);
  PointCloudScene scene(ctx(), view(frame, {3, H, W}), view(disparity, {H, W}), CameraIntrinsics::dvs_default(W, H));
  const Pose a = pose_of(test_poses()[0]), b = pose_of(test_poses()[1]);
  const Rendered ra = render(scene, a), rb = render(scene, b);
  ASSERT_GT(differing(ra.image, rb.image), 0u);
  std::vector<uint8_t> rgba_a(size_t(H) * W * 4), rgba(rgba_a.size());
  scene.render(a, view(rgba_a, {H, W, 4}));
  for (const bool use_a : {true, true, false, true, false, false}) {
    const Rendered r = render(scene, use_a ? a : b);
    EXPECT_EQ(differing(r.image, use_a ? ra.image : rb.image), 0u);
    EXPECT_EQ(differing(r.mask, use_a ? ra.mask : rb.mask), 0u);
    scene.render(use_a ? a : b, view(rgba, {H, W, 4}));
    EXPECT_EQ(differing(rgba, rgba_a) == 0, use_a);
  }
}

void expect_error(const std::function<void()>& f, const std::string& part) {
  try {
    f();
    ADD_FAILURE() << "no error; expected one containing: " << part;
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

TEST_F(PointCloudSceneTest, WrongViewsAreRefusedNamingTheArgument) {
  std::vector<float> frame = random_planar(H, W, 12), disparity = random_disparity(H, W, 13);
  const CameraIntrinsics K = CameraIntrinsics::dvs_default(W, H);
  expect_error([&] { PointCloudScene s(ctx(), view(frame, {H, W}), view(disparity, {H, W}), K); },
               "frame: expected u8 [H,W,3] or f32 [3,H,W], got f32[37x53]");
  expect_error([&] { PointCloudScene s(ctx(), view(disparity, {H, W, 1}), view(disparity, {H, W}), K); },
               "frame: expected u8 [H,W,3] or f32 [3,H,W], got f32[37x53x1]");
  expect_error([&] { PointCloudScene s(ctx(), view(frame, {3, H, W}), view(disparity, {H - 1, W}), K); },
               "depth: expected f32 [37,53] (the frame's size), got f32[36x53]");
  expect_error([&] { PointCloudScene s(ctx(), view(frame, {3, H, W}), view(disparity, {H, W}), CameraIntrinsics::dvs_default(720, 480)); },
               "intrinsics: they are for 480x720 (HxW) but the frame is 37x53");
  std::vector<float> flat(disparity.size(), 0.5f);
  expect_error([&] { PointCloudScene s(ctx(), view(frame, {3, H, W}), view(flat, {H, W}), K); },
               "depth: the disparity is constant");
  expect_error([&] { PointCloudScene s(ctx(), view(frame, {3, H, W}), HostView{nullptr, ElementType::f32, {H, W}}, K); },
               "depth: the view's data pointer is null");

  PointCloudScene scene(ctx(), view(frame, {3, H, W}), view(disparity, {H, W}), K);
  std::vector<float> out(size_t(4) * H * W);
  expect_error([&] { scene.render(Pose{}, view(out, {H, W, 3})); },
               "image: expected f32 [3,37,53] or u8 [37,53,4] (the scene's size), got f32[37x53x3]");
  expect_error([&] { scene.render(Pose{}, view(out, {3, H, W}), view(out, {H, W + 1})); },
               "mask: expected f32 [37,53], got f32[37x54]");
  Pose nan;
  nan.m[5] = std::nan("");
  expect_error([&] { scene.render(nan, view(out, {3, H, W})); }, "pose: element (1, 1) is not finite");
}

// An application's buffer (created here on the context's device, as an app would on its own): the device path
// writes the same bytes the host path returns.
TEST_F(PointCloudSceneTest, DevicePathEqualsHostPath) {
  std::vector<float> frame = random_planar(H, W, 14), disparity = random_disparity(H, W, 15);
  PointCloudScene scene(ctx(), view(frame, {3, H, W}), view(disparity, {H, W}), CameraIntrinsics::dvs_default(W, H));
  vk::Context& v = ctx().internal();
  const VkDeviceSize image_bytes = 3 * H * W * 4, mask_offset = image_bytes + 16, bytes = mask_offset + H * W * 4;
  VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bi.size = bytes;
  bi.usage = VK_BUFFER_USAGE_TRANSFER_DST_BIT | VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  VkBuffer buffer = VK_NULL_HANDLE;
  ASSERT_EQ(vkCreateBuffer(v.device(), &bi, nullptr, &buffer), VK_SUCCESS);
  VkMemoryRequirements req;
  vkGetBufferMemoryRequirements(v.device(), buffer, &req);
  VkPhysicalDeviceMemoryProperties props;
  vkGetPhysicalDeviceMemoryProperties(v.physical_device(), &props);
  const VkMemoryPropertyFlags want = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  uint32_t type = UINT32_MAX;
  for (uint32_t i = 0; i < props.memoryTypeCount && type == UINT32_MAX; ++i)
    if ((req.memoryTypeBits >> i & 1) && (props.memoryTypes[i].propertyFlags & want) == want) type = i;
  ASSERT_NE(type, UINT32_MAX);
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = type;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  ASSERT_EQ(vkAllocateMemory(v.device(), &ai, nullptr, &memory), VK_SUCCESS);
  ASSERT_EQ(vkBindBufferMemory(v.device(), buffer, memory, 0), VK_SUCCESS);
  void* mapped = nullptr;
  ASSERT_EQ(vkMapMemory(v.device(), memory, 0, VK_WHOLE_SIZE, 0, &mapped), VK_SUCCESS);

  for (const glm::dmat4& T : test_poses()) {
    const Rendered host = render(scene, pose_of(T));
    const uint64_t ticket = scene.render(pose_of(T), DeviceBufferView{buffer, 0, ElementType::f32, {3, H, W}},
                                         DeviceBufferView{buffer, mask_offset, ElementType::f32, {H, W}});
    ASSERT_TRUE(ctx().wait(ticket));
    std::fill_n(static_cast<float*>(mapped), 3 * H * W, 9.0f);  // the application reuses its buffer...
    ASSERT_TRUE(ctx().wait(scene.render(pose_of(T), DeviceBufferView{buffer, 0, ElementType::f32, {3, H, W}},
                                        DeviceBufferView{buffer, mask_offset, ElementType::f32, {H, W}})));  // ...same pose
    const auto* f = static_cast<const float*>(mapped);
    EXPECT_EQ(differing(host.image, std::vector<float>(f, f + 3 * H * W)), 0u);
    const auto* m = reinterpret_cast<const float*>(static_cast<const uint8_t*>(mapped) + mask_offset);
    EXPECT_EQ(differing(host.mask, std::vector<float>(m, m + H * W)), 0u);

    std::vector<uint8_t> rgba(size_t(H) * W * 4);
    scene.render(pose_of(T), view(rgba, {H, W, 4}));
    ASSERT_TRUE(ctx().wait(scene.render(pose_of(T), DeviceBufferView{buffer, 4, ElementType::u8, {H, W, 4}})));
    const auto* p = static_cast<const uint8_t*>(mapped) + 4;
    EXPECT_EQ(differing(rgba, std::vector<uint8_t>(p, p + rgba.size())), 0u);
  }
  expect_error([&] { scene.render(Pose{}, DeviceBufferView{buffer, mask_offset, ElementType::f32, {3, H, W}}); },
               "needs bytes");  // past the buffer's end
  expect_error([&] { scene.render(Pose{}, DeviceBufferView{buffer, 0, ElementType::f32, {H, W, 3}}); },
               "image: expected f32 [3,37,53] or u8 [37,53,4]");
  vkUnmapMemory(v.device(), memory);
  vkDestroyBuffer(v.device(), buffer, nullptr);
  vkFreeMemory(v.device(), memory, nullptr);
}

std::string json_number(double v) {
  char s[40];
  std::snprintf(s, sizeof s, "%.17g", v);
  return s;
}

// The program and the call agree: `dvs render` of a one-frame clip (a u8 frame array) with a one-pose JSON path
// writes the mask (exact, mask.npy) the scene renders from the same frame, disparity and pose with the default
// intrinsics, soft and hard. The size is a multiple of 8, as `dvs render --size` requires.
TEST_F(PointCloudSceneTest, EqualsDvsRenderAtAPose) {
  constexpr int h = 40, w = 56;
  test::TempDir dir;
  std::vector<uint8_t> rgb8 = random_rgb8(h, w, 16);
  std::vector<float> disparity = random_disparity(h, w, 17);
  HostTensor frames({1, h, w, 3}, DType::u8), depth({1, h, w}, DType::f32);
  std::copy(rgb8.begin(), rgb8.end(), frames.as<uint8_t>());
  std::copy(disparity.begin(), disparity.end(), depth.as<float>());
  write_npy(dir / "frame.npy", frames);
  write_npy(dir / "depth.npy", depth);
  const glm::dmat4 T = test_poses()[0];
  const Pose pose = pose_of(T);
  std::string poses = "{\"convention\": \"world_to_camera\", \"axes\": \"opencv\", \"poses\": [[";
  for (int i = 0; i < 16; ++i) poses += (i ? ", " : "") + json_number(pose.m[size_t(i)]);
  test::write_text(dir / "path.json", poses + "]]}");
  for (const bool hard : {false, true}) {
    const std::string out = (dir / (hard ? "hard" : "soft")).string();
    const auto r = test::run_command(test::program("dvs") + " render --video " + (dir / "frame.npy").string() +
                                     " --depth " + (dir / "depth.npy").string() + " --trajectory " +
                                     (dir / "path.json").string() + " --size 40x56 --frames 1 --no-glb" +
                                     (hard ? " --points" : "") + " --out " + out);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const HostTensor program_mask = read_npy(std::filesystem::path(out) / "mask.npy");
    ASSERT_EQ(program_mask.shape, (Shape{1, h, w}));
    PointCloudScene scene(ctx(), view(rgb8, {h, w, 3}), view(disparity, {h, w}), CameraIntrinsics::dvs_default(w, h),
                          {true, hard});
    std::vector<float> image(size_t(3) * h * w), mask(size_t(h) * w);
    scene.render(pose, view(image, {3, h, w}), view(mask, {h, w}));
    size_t visible = 0, holes = 0;
    for (float m : mask) (m > 0 ? visible : holes) += 1;
    EXPECT_GT(holes, 0u);  // the pose uncovers something: the comparison is not all ones
    EXPECT_GT(visible, holes);
    EXPECT_EQ(differing(mask, std::vector<float>(program_mask.as<float>(), program_mask.as<float>() + h * w)), 0u);
  }
}

}  // namespace
}  // namespace dvs
