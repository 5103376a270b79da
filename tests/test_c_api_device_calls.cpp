// The C API's device-buffer forms of the whole run and the depth estimate (dvs/dvs.h: dvs_run_pipeline_clip_device,
// dvs_depth_estimator_estimate_device), called as an engine would, on the test application's device
// (support/app_device.hpp: synchronization validation across submissions): the values in its buffers equal the
// host-memory forms' (dvs_run_pipeline_clip, dvs_depth_estimator_estimate) byte for byte, and a missing buffer is
// refused with the status and a message naming it. (tests/test_c_api.c checks that dvs.h compiles as C99.)
#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <vector>

#include "dvs/dvs.h"
#include "dvs/video.hpp"
#include "io/npy.hpp"
#include "support/app_device.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/random_vda.hpp"

namespace dvs {
namespace {

constexpr int F = 9, H = 64, W = 64;

dvs_context* context_on(test::AppDevice& app) {
  const HostDevice h = app.host();
  dvs_host_device c{};
  c.instance = h.instance, c.physical_device = h.physical_device, c.device = h.device;
  c.queue_family = h.queue_family, c.queue = h.queue, c.instance_api_version = h.instance_api_version;
  c.enabled_features = h.enabled_features;
  dvs_context* ctx = nullptr;
  EXPECT_EQ(dvs_context_create_on_host(&c, &ctx), DVS_OK) << dvs_last_error();
  return ctx;
}

dvs_buffer_range range(const test::AppDevice::Buffer& b) { return {b.buffer, 0}; }

bool same(const test::AppDevice::Buffer& b, const void* want, size_t bytes) { return std::memcmp(b.data, want, bytes) == 0; }

TEST(CApiDeviceCalls, AWholeRunOnTheApplicationsBuffersGivesTheHostFormsBytes) {
  test::PipelineInputs in;
  const VideoFrames frames = read_video_frames(in.video, 0, F, H, W);
  const HostTensor depth = read_npy(in.depth);
  const size_t pixels = size_t(F) * H * W;
  dvs_pipeline_options o;
  ASSERT_EQ(dvs_pipeline_options_default(&o), DVS_OK);
  const std::string model = in.model.string(), cache = (in.dir / "c_cache").string();
  o.model = model.c_str();
  o.cache_dir = cache.c_str();
  o.prompt = "a red fox";
  o.steps = 4, o.inversion_steps = 3, o.use_cache = 0;  // both forms sample (no cached latent in between)
  dvs_render_options r;
  ASSERT_EQ(dvs_render_options_default(&r), DVS_OK);
  r.frames = 0, r.height = H, r.width = W, r.metric_depth = 1;
  o.render = &r;
  int64_t shape[4];
  ASSERT_EQ(dvs_clip_latent_shape(&o, F, H, W, shape), DVS_OK) << dvs_last_error();
  const size_t latent_floats = size_t(shape[0] * shape[1] * shape[2] * shape[3]);

  test::AppDevice app;
  dvs_context* ctx = context_on(app);
  ASSERT_NE(ctx, nullptr);
  // The host form, the reference.
  std::vector<uint8_t> output(pixels * 3);
  std::vector<float> mask(pixels), latent(latent_floats);
  ASSERT_EQ(dvs_run_pipeline_clip(ctx, &o, frames.rgb.data(), F, H, W, depth.as<float>(), nullptr, output.data(),
                                  mask.data(), latent.data(), latent_floats, nullptr, nullptr),
            DVS_OK)
      << dvs_last_error();

  test::AppDevice::Buffer &frames_b = app.buffer(pixels * 3), &depth_b = app.buffer(pixels * 4),
                          &output_b = app.buffer(pixels * 3), &mask_b = app.buffer(pixels * 4),
                          &latent_b = app.buffer(latent_floats * 4);
  std::memcpy(frames_b.data, frames.rgb.data(), pixels * 3);
  std::memcpy(depth_b.data, depth.data.data(), pixels * 4);
  EXPECT_EQ(dvs_run_pipeline_clip_device(ctx, &o, range(frames_b), F, H, W, range(depth_b), nullptr, dvs_buffer_range{},
                                         range(mask_b), range(latent_b), nullptr, nullptr),
            DVS_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(dvs_last_error()).find("ClipResultDeviceViews::output"), std::string::npos) << dvs_last_error();
  ASSERT_EQ(dvs_run_pipeline_clip_device(ctx, &o, range(frames_b), F, H, W, range(depth_b), nullptr, range(output_b),
                                         range(mask_b), range(latent_b), nullptr, nullptr),
            DVS_OK)
      << dvs_last_error();
  EXPECT_TRUE(same(output_b, output.data(), output.size())) << "the output differs from the host form's";
  EXPECT_TRUE(same(mask_b, mask.data(), mask.size() * 4)) << "the mask differs";
  EXPECT_TRUE(same(latent_b, latent.data(), latent.size() * 4)) << "the latent differs";
  EXPECT_EQ(dvs_context_destroy(ctx), DVS_OK);
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

TEST(CApiDeviceCalls, ADepthEstimateOnTheApplicationsBuffersGivesTheHostFormsValues) {
  test::PipelineInputs in;
  const std::string model = test::random_vda(in.dir / "vda").string();
  const VideoFrames frames = read_video_frames(in.video, 0, F, H, W);
  const size_t pixels = size_t(F) * H * W;
  test::AppDevice app;
  dvs_context* ctx = context_on(app);
  ASSERT_NE(ctx, nullptr);
  dvs_depth_estimator* estimator = nullptr;
  ASSERT_EQ(dvs_depth_estimator_create(ctx, model.c_str(), 28, -1, &estimator), DVS_OK) << dvs_last_error();
  std::vector<float> want(pixels);
  ASSERT_EQ(dvs_depth_estimator_estimate(estimator, frames.rgb.data(), F, H, W, want.data(), nullptr, nullptr), DVS_OK)
      << dvs_last_error();
  test::AppDevice::Buffer &frames_b = app.buffer(pixels * 3), &out_b = app.buffer(pixels * 4);
  std::memcpy(frames_b.data, frames.rgb.data(), pixels * 3);
  EXPECT_EQ(dvs_depth_estimator_estimate_device(estimator, dvs_buffer_range{}, F, H, W, range(out_b), nullptr, nullptr),
            DVS_ERROR_INVALID_ARGUMENT);
  EXPECT_NE(std::string(dvs_last_error()).find("VK_NULL_HANDLE"), std::string::npos) << dvs_last_error();
  ASSERT_EQ(dvs_depth_estimator_estimate_device(estimator, range(frames_b), F, H, W, range(out_b), nullptr, nullptr),
            DVS_OK)
      << dvs_last_error();
  EXPECT_TRUE(same(out_b, want.data(), want.size() * 4)) << "the disparity differs from the host form's";
  EXPECT_EQ(dvs_depth_estimator_destroy(estimator), DVS_OK);
  EXPECT_EQ(dvs_context_destroy(ctx), DVS_OK);
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

}  // namespace
}  // namespace dvs
