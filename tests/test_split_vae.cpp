// The VAE at the real CogVideoX-5B-I2V size (480 x 720, widths 128/256/256/512) against the allocation limit:
// its working-set planner (a dry run of the same layer code, no device work) gives the working set and the
// largest single buffer of encode (1 frame, the image-conditioning call) and decode (1 latent frame -> 1 frame,
// 2 latent frames -> 5 frames), untiled and with 240 x 360 tiles (30 x 45 latent). Every buffer must fit one
// allocation on any Vulkan device: 1 GiB (the minimum maxMemoryAllocationSize Vulkan allows) -- except the
// untiled decode of 2+ latent frames, whose full-resolution activations (256 x 8 x 480 x 720 f32 = 2.6 GiB)
// exceed even lavapipe's 2 GiB: CogVideoXVae::decode refuses that call up front and names the tiling.
// (Smaller frame batches would change GroupNorm's per-batch statistics and, below 2 latent frames, the frame
// count, so tiling is the only exact way down.) Bindings of all these buffers are split by the ops
// themselves (test_split_conv.cpp).
#include <gtest/gtest.h>

#include <cstdio>

#include "models/cogvideox/cogvideox_vae.hpp"
#include "pipeline/memory_plan.hpp"

namespace dvs {
namespace {

using models::CogVideoXVae;
using models::VaeFootprint;

const nlohmann::json& real_config() {
  static const nlohmann::json j = pipeline::builtin_plan_model("cogvideox-5b-i2v").vae;
  return j;
}

constexpr uint64_t kMinAlloc = 1ull << 30;  // Vulkan's minimum maxMemoryAllocationSize

void report(const char* what, const VaeFootprint& f) {
  const double mib = 1024.0 * 1024.0;
  std::printf("[ plan   ] VAE %-34s working %8.1f MiB, largest tensor %7.1f MiB\n", what, f.working / mib,
              f.largest_tensor / mib);
}

TEST(SplitVae, RealSizeBuffersFitOneAllocation) {
  struct Call {
    const char* what;
    bool encode;
    Shape shape;
    bool fits = true;  // largest tensor within 1 GiB
  };
  const Call calls[] = {
      {"encode 1 frame 480x720", true, {1, 3, 1, 480, 720}},
      {"encode 1 frame, tile 240x360", true, {1, 3, 1, 240, 360}},
      {"decode 1 latent frame 60x90", false, {1, 16, 1, 60, 90}},
      {"decode 1 latent frame, tile 30x45", false, {1, 16, 1, 30, 45}},
      {"decode 2 latent frames 60x90", false, {1, 16, 2, 60, 90}, false},
      {"decode 2 latent frames, tile 30x45", false, {1, 16, 2, 30, 45}},
      {"decode 13 latent frames 60x90", false, {1, 16, 13, 60, 90}, false},
      {"decode 13 latent frames, tile 30x45", false, {1, 16, 13, 30, 45}},
  };
  for (const Call& c : calls) {
    const VaeFootprint f = c.encode ? CogVideoXVae::encode_footprint(real_config(), c.shape)
                                    : CogVideoXVae::decode_footprint(real_config(), c.shape);
    report(c.what, f);
    EXPECT_GT(f.largest_tensor, 0u) << c.what;
    EXPECT_LE(f.largest_tensor, f.working) << c.what;
    if (c.fits) {
      EXPECT_LE(f.largest_tensor, kMinAlloc) << c.what << ": a buffer over 1 GiB cannot be allocated on every device";
    } else {
      EXPECT_GT(f.largest_tensor, 2 * kMinAlloc) << c.what << ": expected over lavapipe's 2 GiB (refused, tiling needed)";
    }
    EXPECT_EQ(f.working, c.encode ? CogVideoXVae::encode_working_bytes(real_config(), c.shape)
                                  : CogVideoXVae::decode_working_bytes(real_config(), c.shape))
        << c.what;
  }
}

// The largest buffer of a decode is the widest activation at full resolution: 128 channels x the batch's
// output frames x 480 x 720 f32 (the planner is exact, so this is a check of it, not a bound).
TEST(SplitVae, LargestTensorIsTheFullResolutionActivation) {
  const VaeFootprint one = CogVideoXVae::decode_footprint(real_config(), {1, 16, 1, 60, 90});
  EXPECT_GE(one.largest_tensor, uint64_t(128) * 480 * 720 * 4);
  const VaeFootprint two = CogVideoXVae::decode_footprint(real_config(), {1, 16, 2, 60, 90});
  EXPECT_GT(two.largest_tensor, one.largest_tensor);
}

}  // namespace
}  // namespace dvs
