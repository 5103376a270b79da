// dvs::DepthEstimator (dvs/depth_frames.hpp) with a tiny random Video-Depth-Anything model: the disparity of frames
// in memory equals estimate_depth's .npy of the same video bit for bit (the frames decoded by the production
// decoder), the model is loaded once (the checkpoint can go after the constructor), wrong views are named, and a
// cancellation stops the estimate and leaves the estimator usable; the device-buffer form gives the same values.
#include <gtest/gtest.h>

#include <cstring>

#include "dvs/context.hpp"
#include "dvs/depth_estimate.hpp"
#include "dvs/depth_frames.hpp"
#include "dvs/error.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "support/app_device.hpp"
#include "support/expect_error.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/random_vda.hpp"
#include "vk/context.hpp"

namespace dvs {
namespace {

class DepthEstimatorTest : public ::testing::Test {
 protected:
  static constexpr int kFrames = 9, kInputSize = 28;
  test::PipelineInputs in;
  std::filesystem::path model = test::random_vda(in.dir / "vda");
  HostTensor frames = read_video_rgb8(in.video, kFrames);
  Context ctx{validating()};

  static ContextOptions validating() {
    ContextOptions o;
    o.validation = true;
    return o;
  }
  void TearDown() override {
    const auto messages = ctx.internal().validation_messages();
    EXPECT_TRUE(messages.empty()) << messages.size() << " validation message(s), first: " << messages[0];
  }

  DepthModelOptions options() const {
    DepthModelOptions o;
    o.input_size = kInputSize;
    return o;
  }
  HostView frames_view() {
    return {frames.data.data(), ElementType::u8, frames.shape};
  }
  HostView out_view(std::vector<float>& out) {
    out.assign(size_t(frames.shape[0] * frames.shape[1] * frames.shape[2]), -7.f);
    return {out.data(), ElementType::f32, {frames.shape[0], frames.shape[1], frames.shape[2]}};
  }
};

TEST_F(DepthEstimatorTest, EqualsDvsDepthOfTheSameVideoBitForBit) {
  DepthJob job;
  job.video = in.video;
  job.model = model;
  job.input_size = kInputSize;
  job.frames = kFrames;
  job.cache_dir = in.cache;
  estimate_depth(job, in.dir / "d.npy");
  const HostTensor expected = read_npy(in.dir / "d.npy");

  DepthEstimator estimator(ctx, model, options());
  EXPECT_FALSE(estimator.metric());
  std::vector<float> out;
  estimator.estimate(frames_view(), out_view(out));
  ASSERT_EQ(expected.shape, (Shape{kFrames, 64, 64}));
  ASSERT_EQ(expected.bytes(), out.size() * sizeof(float));
  EXPECT_EQ(std::memcmp(expected.data.data(), out.data(), expected.bytes()), 0) << "not the estimate of dvs depth";
}

TEST_F(DepthEstimatorTest, TheModelIsLoadedOnceAndStaysLoaded) {
  DepthEstimator estimator(ctx, model, options());
  // Were a call to read the checkpoint again, it would fail now.
  std::filesystem::remove(model);
  std::vector<float> first, second;
  estimator.estimate(frames_view(), out_view(first));
  estimator.estimate(frames_view(), out_view(second));
  EXPECT_EQ(first, second);
  EXPECT_NE(first[0], -7.f) << "nothing was written";
}

TEST_F(DepthEstimatorTest, WrongViewsAreNamed) {
  DepthEstimator estimator(ctx, model, options());
  std::vector<float> out;
  const HostView good_out = out_view(out);
  auto message = [&](const HostView& f, const HostView& o) -> std::string {
    try {
      estimator.estimate(f, o);
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  };
  HostView rgba = frames_view();
  rgba.shape = {kFrames, 64, 16, 4};  // the same bytes, but four channels
  std::string m = message(rgba, good_out);
  EXPECT_NE(m.find("frames must be u8 [F,H,W,3]"), std::string::npos) << m;
  EXPECT_NE(m.find("u8[9x64x16x4]"), std::string::npos) << m;
  HostView as_f32 = frames_view();
  as_f32.type = ElementType::f32;
  as_f32.shape = {kFrames, 64, 16, 3};
  m = message(as_f32, good_out);
  EXPECT_NE(m.find("frames must be u8"), std::string::npos) << m;
  HostView short_out = good_out;
  short_out.shape = {kFrames - 1, 64, 64};
  m = message(frames_view(), short_out);
  EXPECT_NE(m.find("out must be f32 [9x64x64]"), std::string::npos) << m;
  EXPECT_NE(m.find("f32[8x64x64]"), std::string::npos) << m;
  HostView no_memory = good_out;
  no_memory.data = nullptr;
  m = message(frames_view(), no_memory);
  EXPECT_NE(m.find("out.data is null"), std::string::npos) << m;
  EXPECT_EQ(out[0], -7.f) << "a refused call wrote its output";
}

TEST_F(DepthEstimatorTest, TheDeviceFormTakesAndGivesTheApplicationsBuffersWithTheSameValues) {
  // Frames in the application's buffer, the disparity out to another, on its device (synchronization validation
  // across submissions): the values of the host form, bit for bit; wrong buffers named before any work.
  std::vector<float> want;
  {
    DepthEstimator estimator(ctx, model, options());
    estimator.estimate(frames_view(), out_view(want));
  }
  test::AppDevice app;
  ContextOptions co;
  co.pipeline_cache_file = "-";
  Context on_app(app.host(), co);
  DepthEstimator estimator(on_app, model, options());
  const std::vector<int64_t> fhw{frames.shape[0], frames.shape[1], frames.shape[2]};
  test::AppDevice::Buffer& in_buffer = app.buffer(frames.bytes());
  test::AppDevice::Buffer& out_buffer = app.buffer(want.size() * sizeof(float));
  std::memcpy(in_buffer.data, frames.data.data(), frames.bytes());
  const DeviceBufferView in_view{in_buffer.buffer, 0, ElementType::u8, frames.shape};
  const DeviceBufferView out_view_device{out_buffer.buffer, 0, ElementType::f32, fhw};
  test::AppDevice::Buffer& small = app.buffer(16);
  int events = 0;
  const ProgressFn count = [&](const std::string&, int, int, const std::string&) { ++events; };
  test::expect_error([&] { estimator.estimate(in_view, DeviceBufferView{small.buffer, 0, ElementType::f32, fhw}, count); },
                     {"DepthEstimator::estimate's out", "holds at most"});
  test::expect_error([&] { estimator.estimate(DeviceBufferView{}, out_view_device, count); }, {"frames must be u8"});
  EXPECT_EQ(events, 0) << "a refused estimate began work";
  estimator.estimate(in_view, out_view_device);
  EXPECT_EQ(std::memcmp(out_buffer.data, want.data(), want.size() * sizeof(float)), 0)
      << "the disparity in the application's buffer differs from the host form's";
  EXPECT_EQ(app.locks, app.unlocks);
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

TEST_F(DepthEstimatorTest, AMissingModelIsNamed) {
  try {
    DepthEstimator estimator(ctx, in.dir / "none.pth", options());
    ADD_FAILURE() << "a missing model was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("none.pth: no such depth model"), std::string::npos) << e.what();
  }
}

TEST_F(DepthEstimatorTest, CancellationStopsAndTheEstimatorStaysUsable) {
  DepthEstimator estimator(ctx, model, options());
  std::vector<float> out;
  int steps = 0;
  bool cancel = false;
  auto progress = [&](const std::string& stage, int step, int, const std::string&) {
    EXPECT_EQ(stage, "depth");
    ++steps;
    if (step == 2) cancel = true;
  };
  EXPECT_THROW(estimator.estimate(frames_view(), out_view(out), progress, [&] { return cancel; }), Cancelled);
  EXPECT_EQ(steps, 2) << "steps ran after the cancellation was asked for";
  EXPECT_EQ(out[0], -7.f) << "a cancelled estimate wrote its output";
  cancel = false;
  estimator.estimate(frames_view(), out_view(out));
  EXPECT_NE(out[0], -7.f);
}

}  // namespace
}  // namespace dvs
