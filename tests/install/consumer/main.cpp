// An application that uses the installed dvs: creates a context on dvs's own device and prints it, checks that an
// error thrown inside libdvs is caught here by its type (dvs::UsageError: the typeinfo is exported), and renders a
// synthetic frame with dvs::PointCloudScene at the identity pose. The expectation is independent of dvs's code:
// at the identity every pixel's point projects back onto its own pixel centre, where the soft bilinear splat gives
// it weight 1 and no neighbour any weight, so every visible pixel must hold the input value, and with a flat depth
// every pixel is visible. Exit status 0 = all good.
#include <dvs/context.hpp>
#include <dvs/error.hpp>
#include <dvs/info.hpp>
#include <dvs/lora.hpp>
#include <dvs/scene.hpp>
#include <dvs/usage_error.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace {

// Renders a W×H frame of distinct colours over a flat disparity at the identity and compares by value.
int check_identity_render(dvs::Context& ctx) {
  const int W = 24, H = 16;
  std::vector<uint8_t> frame(size_t(W) * H * 3);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      for (int c = 0; c < 3; ++c) frame[(size_t(y) * W + x) * 3 + c] = uint8_t((x * 10 + y * 7 + c * 80) % 256);
  std::vector<float> depth(size_t(W) * H, 2.0f);  // metric depth: a plane facing the camera
  const dvs::HostView frame_view{frame.data(), dvs::ElementType::u8, {H, W, 3}};
  const dvs::HostView depth_view{depth.data(), dvs::ElementType::f32, {H, W}};
  dvs::SceneOptions options;
  options.depth_is_disparity = false;
  dvs::PointCloudScene scene(ctx, frame_view, depth_view, dvs::CameraIntrinsics::dvs_default(W, H), options);

  std::vector<float> image(size_t(3) * H * W, 7.0f), mask(size_t(H) * W, 7.0f);
  scene.render(dvs::Pose{}, dvs::HostView{image.data(), dvs::ElementType::f32, {3, H, W}},
               dvs::HostView{mask.data(), dvs::ElementType::f32, {H, W}});
  int visible = 0, wrong = 0;
  double worst = 0;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      if (mask[size_t(y) * W + x] != 1.0f) continue;
      ++visible;
      for (int c = 0; c < 3; ++c) {
        const double want = frame[(size_t(y) * W + x) * 3 + c] / 127.5 - 1.0;  // dvs's [−1, 1] levels
        const double err = std::fabs(image[(size_t(c) * H + y) * W + x] - want);
        worst = std::max(worst, err);
        // The f32 reprojection moves a point by a few 1e-6 px, so a neighbour gets a weight of that order: the
        // value stays within an eighth of one 8-bit level (1/127.5) and rounds back to the input's level.
        if (err > 1e-3) ++wrong;
      }
    }
  std::printf("identity render: %d of %d pixels visible, largest difference %.3g\n", visible, W * H, worst);
  if (visible != W * H) {
    std::fprintf(stderr, "consumer: only %d of %d pixels are visible at the identity pose\n", visible, W * H);
    return 1;
  }
  if (wrong > 0) {
    std::fprintf(stderr, "consumer: %d channel values differ from the input frame by more than 1e-3\n", wrong);
    return 1;
  }
  return 0;
}

}  // namespace

int main() {
  try {
    dvs::Context ctx;
    std::printf("dvs %s on %s\n", dvs::version(), ctx.device_name().c_str());
    if (ctx.device_name().empty()) {
      std::fprintf(stderr, "consumer: the context names no device\n");
      return 1;
    }
    if (check_identity_render(ctx) != 0) return 1;
  } catch (const dvs::Error& e) {
    std::fprintf(stderr, "consumer: %s\n", e.what());
    return 1;
  }

  try {
    dvs::parse_lora_argument("adapter.safetensors:not-a-number");
    std::fprintf(stderr, "consumer: a malformed --lora argument was accepted\n");
    return 1;
  } catch (const dvs::UsageError& e) {
    std::printf("caught dvs::UsageError from the library: %s\n", e.what());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "consumer: expected a dvs::UsageError, caught another exception: %s\n", e.what());
    return 1;
  }
  return 0;
}
