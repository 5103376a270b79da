// dvs::PointCloudScene::render (dvs/scene.hpp) at 480×720, the preview's frame time: wall ms per call from the
// pose to the result in the caller's memory, for the f32 host path, the RGBA8 host path (packed on the device)
// and the device path (into a buffer of the context's device), each with a new pose every call (recorded again)
// and with a still camera (the recording replayed). Runs on a dvs::Context of its own (DVS_DEVICE picks it).
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>
#include <vector>

#include "dvs/context.hpp"
#include "dvs/scene.hpp"
#include "geometry/trajectory.hpp"
#include "harness.hpp"
#include "vk/memory.hpp"

namespace dvs::bench {
namespace {

Pose pose_at(int i) {  // a slow orbit: every call a new pose
  const glm::dmat4 T = geometry::rotation_y(0.002 * i) * geometry::translation({0.001 * i, 0, 0});
  Pose p;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) p.m[size_t(r * 4 + c)] = T[c][r];
  return p;
}

void scene(Bench& b) {
  const int H = 480, W = 720;
  std::vector<uint8_t> frame(size_t(H) * W * 3);
  std::vector<float> disparity(size_t(H) * W);
  std::mt19937 g(1);
  for (auto& v : frame) v = uint8_t(g() & 255);
  for (int y = 0; y < H; ++y)  // a floor rising to a wall, with a nearer box
    for (int x = 0; x < W; ++x)
      disparity[size_t(y) * W + x] = (x > 250 && x < 450 && y > 150 && y < 350) ? 0.9f : 0.2f + 0.5f * float(y) / H;
  Context ctx;
  PointCloudScene s(ctx, {frame.data(), ElementType::u8, {H, W, 3}}, {disparity.data(), ElementType::f32, {H, W}},
                    CameraIntrinsics::dvs_default(W, H));
  std::vector<float> image(size_t(3) * H * W), mask(size_t(H) * W);
  std::vector<uint8_t> rgba(size_t(H) * W * 4);
  vk::Buffer device_image = ctx.internal().allocator().allocate(uint64_t(H) * W * 4 * 4, vk::MemoryUse::device,
                                                                "bench scene image");
  const HostView f32_view{image.data(), ElementType::f32, {3, H, W}}, mask_view{mask.data(), ElementType::f32, {H, W}};
  const HostView rgba_view{rgba.data(), ElementType::u8, {H, W, 4}};
  const DeviceBufferView dev_f32{device_image.view().buffer, device_image.view().offset, ElementType::f32, {3, H, W}};
  const DeviceBufferView dev_rgba{device_image.view().buffer, device_image.view().offset, ElementType::u8, {H, W, 4}};
  struct Case {
    const char* name;
    std::function<void(const Pose&)> call;
  };
  const std::vector<Case> cases = {
      {"scene_host_f32", [&](const Pose& p) { s.render(p, f32_view, mask_view); }},
      {"scene_host_rgba8", [&](const Pose& p) { s.render(p, rgba_view); }},
      {"scene_device_rgba8", [&](const Pose& p) { ctx.wait(s.render(p, dev_rgba)); }},
      {"scene_device_f32", [&](const Pose& p) { ctx.wait(s.render(p, dev_f32)); }},
  };
  const double seconds = b.quick() ? 0.5 : 2.0;
  for (const Case& c : cases) {
    int i = 0;
    const double moving = Bench::time_ms([&] { c.call(pose_at(++i)); }, seconds);
    const Pose still = pose_at(0);
    const double replay = Bench::time_ms([&] { c.call(still); }, seconds);
    char note[160];
    std::snprintf(note, sizeof note, "%.1f frames/s with a new pose each call; %.2f ms (%.1f frames/s) still camera",
                  1000.0 / moving, replay, 1000.0 / replay);
    b.report({c.name, "480x720", moving, 0, 0, note});
  }
}

Registration reg("scene", 20, scene);

}  // namespace
}  // namespace dvs::bench
