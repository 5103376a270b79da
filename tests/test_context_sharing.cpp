// One dvs::Context used carelessly (issue 34 §2.1, §2.2): calls from two threads, a render loop beside a job, a second
// context on the same device (dvs's own, and an application's with its queue lock), the context destroyed before a
// scene made on it and under a running job. The references are the same work done alone on a context nothing else
// uses: a run's output and latent, a scene's render at two poses, byte for byte.
//
// Where a test needs "while the job runs", the job's progress callback (on the job's thread, which holds the context)
// waits for the test to have done its part, so the overlap is certain, not a matter of timing.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <thread>

#include "dvs/clip_run.hpp"
#include "dvs/error.hpp"
#include "dvs/scene.hpp"
#include "dvs/video.hpp"
#include "io/npy.hpp"
#include "pipeline/clip_input.hpp"
#include "support/app_device.hpp"
#include "support/pipeline_inputs.hpp"

namespace dvs {
namespace {

constexpr int F = 9, H = 64, W = 64;
using Clock = std::chrono::steady_clock;

// A one-shot signal between threads.
class Latch {
 public:
  void open() {
    std::lock_guard<std::mutex> lock(mutex_);
    open_ = true;
    changed_.notify_all();
  }
  void wait() {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [this] { return open_; });
  }
  bool is_open() {
    std::lock_guard<std::mutex> lock(mutex_);
    return open_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  bool open_ = false;
};

struct RunResult {
  std::vector<uint8_t> output = std::vector<uint8_t>(size_t(F) * H * W * 3);
  std::vector<float> latent;
  Clock::time_point first, last;  // the first and last progress event
  explicit RunResult(const std::vector<int64_t>& latent_shape)
      : latent(size_t(latent_shape[0] * latent_shape[1] * latent_shape[2] * latent_shape[3])) {}
};

class ContextSharing : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    in = new test::PipelineInputs;
    frames = new VideoFrames(read_video_frames(in->video, 0, F, H, W));
    depth = new HostTensor(read_npy(in->depth));
  }
  static void TearDownTestSuite() {
    delete depth;
    delete frames;
    delete in;
  }

  static RunOptions options() {
    RunOptions o = in->run_options({}, in->dir / "cache");
    o.render.video.clear();
    o.render.depth.clear();
    o.render.out_dir.clear();
    o.use_cache = false;  // every run samples
    return o;
  }
  static ClipView clip() {
    ClipView c;
    c.frames = {frames->rgb.data(), ElementType::u8, {F, H, W, 3}};
    c.depth = {depth->data.data(), ElementType::f32, {F, H, W}};
    return c;
  }
  static std::vector<int64_t> latent_shape() { return clip_latent_shape(in->model, F, H, W); }
  static ClipResultViews views(RunResult& r) {
    ClipResultViews v;
    v.output = {r.output.data(), ElementType::u8, {F, H, W, 3}};
    v.latent = {r.latent.data(), ElementType::f32, latent_shape()};
    return v;
  }
  // A progress callback noting the first and last event's time.
  static ProgressFn timing(RunResult& r) {
    return [&r](const std::string&, int, int, const std::string&) {
      if (r.first == Clock::time_point{}) r.first = Clock::now();
      r.last = Clock::now();
    };
  }
  // The run alone on a context of its own: the reference.
  static const RunResult& alone() {
    static std::unique_ptr<RunResult> r;
    if (!r) {
      r = std::make_unique<RunResult>(latent_shape());
      Context ctx;
      run_pipeline(ctx, options(), clip(), views(*r));
    }
    return *r;
  }

  // The scene of frame 0 with its metric depth, and the two poses the tests alternate (so each render splats anew).
  static std::unique_ptr<PointCloudScene> scene_on(Context& ctx) {
    SceneOptions so;
    so.depth_is_disparity = false;
    return std::make_unique<PointCloudScene>(ctx, ConstHostView{frames->rgb.data(), ElementType::u8, {H, W, 3}},
                                             ConstHostView{depth->data.data(), ElementType::f32, {H, W}},
                                             CameraIntrinsics::dvs_default(W, H), so);
  }
  static Pose pose(int i) {
    Pose p;
    p.m[3] = i % 2 ? 0.05 : -0.03;
    return p;
  }
  static std::vector<uint8_t> render(PointCloudScene& s, int i) {
    std::vector<uint8_t> rgba(size_t(H) * W * 4);
    s.render(pose(i), HostView{rgba.data(), ElementType::u8, {H, W, 4}});
    return rgba;
  }
  // The renders at both poses on a context nothing else uses.
  static const std::vector<std::vector<uint8_t>>& renders_alone() {
    static std::vector<std::vector<uint8_t>> r;
    if (r.empty()) {
      Context ctx;
      auto s = scene_on(ctx);
      r = {render(*s, 0), render(*s, 1)};
    }
    return r;
  }

  // The kind and message of the dvs::Error f() throws (anything else fails the test).
  template <class Call>
  static std::pair<ErrorKind, std::string> error_of(Call&& f) {
    try {
      f();
    } catch (const Error& e) {
      return {e.kind(), e.what()};
    } catch (const std::exception& e) {
      ADD_FAILURE() << "not a dvs::Error: " << e.what();
      return {ErrorKind::internal, e.what()};
    }
    ADD_FAILURE() << "no error";
    return {ErrorKind::internal, ""};
  }

  // A job on `ctx` whose first progress event waits until release() (so "while the job runs" is certain); made, it
  // is waiting there.
  struct HeldJob {
    Latch started, released;
    RunResult result{latent_shape()};
    Job job;
    explicit HeldJob(Context& ctx)
        : job(start_pipeline(ctx, options(), clip(), views(result), [this](const std::string&, int, int, const std::string&) {
            if (!started.is_open()) {
              started.open();
              released.wait();
            }
          })) {
      started.wait();
    }
    void release() { released.open(); }
  };

  static test::PipelineInputs* in;
  static VideoFrames* frames;
  static HostTensor* depth;
};
test::PipelineInputs* ContextSharing::in = nullptr;
VideoFrames* ContextSharing::frames = nullptr;
HostTensor* ContextSharing::depth = nullptr;

// Two threads run the whole pipeline on one context (this segfaulted at once): the calls are serialised, the one
// waiting for the other (their progress never interleaves), and both give the run's own numbers.
TEST_F(ContextSharing, CallsFromTwoThreadsOnOneContextTakeTurnsAndBothGiveTheRunsNumbers) {
  const RunResult& want = alone();
  Context ctx;
  RunResult a(latent_shape()), b(latent_shape());
  std::thread other([&] { run_pipeline(ctx, options(), clip(), views(a), timing(a)); });
  run_pipeline(ctx, options(), clip(), views(b), timing(b));
  other.join();
  EXPECT_TRUE(a.last < b.first || b.last < a.first) << "the two runs' progress interleaved: they ran at once";
  EXPECT_EQ(a.latent, want.latent);
  EXPECT_EQ(b.latent, want.latent);
  EXPECT_EQ(a.output, want.output);
  EXPECT_EQ(b.output, want.output);
}

// A render loop on the context a job runs on (the segfault of a preview beside start_pipeline): every call on that
// context from another thread is refused while the job holds it, naming the job and the remedy; the job is not
// disturbed, and the scene renders its own image once the job has ended.
TEST_F(ContextSharing, ACallOnTheContextOfARunningJobIsRefusedNamingTheJobAndTheRemedy) {
  const RunResult& want = alone();
  Context ctx;
  auto scene = scene_on(ctx);
  HeldJob held(ctx);
  Job& job = held.job;
  RunResult& r = held.result;
  const auto [kind, message] = error_of([&] { render(*scene, 0); });
  EXPECT_EQ(kind, ErrorKind::invalid_argument);
  for (const char* part : {"dvs::PointCloudScene::render", "the pipeline job on the clip u8[9x64x64x3]",
                           "second dvs::Context", "A preview beside a job"})
    EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
  RunResult beside(latent_shape());
  EXPECT_EQ(error_of([&] { run_pipeline(ctx, options(), clip(), views(beside)); }).first, ErrorKind::invalid_argument);
  EXPECT_EQ(error_of([&] { start_pipeline(ctx, options(), clip(), views(beside)); }).first, ErrorKind::invalid_argument);
  EXPECT_EQ(error_of([&] { ctx.wait(0); }).first, ErrorKind::invalid_argument);
  EXPECT_EQ(error_of([&] { ctx.submitted_value(); }).first, ErrorKind::invalid_argument);
  held.release();
  job.wait();
  ASSERT_EQ(job.poll(), JobState::succeeded) << job.error();
  EXPECT_EQ(r.latent, want.latent);
  EXPECT_EQ(r.output, want.output);
  EXPECT_EQ(render(*scene, 0), renders_alone()[0]) << "the scene after the job";
  EXPECT_EQ(render(*scene, 1), renders_alone()[1]);
}

// The pattern docs/embedding.md shows: the preview on a second context of the same device renders while the job runs
// (the job waits in its first progress event until six renders are done), each render equal to the render alone, and
// the job gives the run's own numbers.
TEST_F(ContextSharing, ASecondContextOnTheSameDeviceRendersBesideTheJob) {
  const RunResult& want = alone();
  const auto& renders = renders_alone();
  Context ctx, preview;
  EXPECT_EQ(ctx.device_name(), preview.device_name());
  auto scene = scene_on(preview);
  HeldJob held(ctx);
  Job& job = held.job;
  RunResult& r = held.result;
  int during = 0;
  for (; during < 6; ++during) ASSERT_EQ(render(*scene, during), renders[size_t(during % 2)]) << "render " << during;
  held.release();
  for (int i = 0; job.poll() == JobState::running; ++i) ASSERT_EQ(render(*scene, i), renders[size_t(i % 2)]);
  ASSERT_EQ(job.poll(), JobState::succeeded) << job.error();
  EXPECT_EQ(r.latent, want.latent);
  EXPECT_EQ(r.output, want.output);
}

// The same on an application's device: two contexts on one HostDevice share its queue. dvs serialises its own
// submissions to it, so the application's queue lock is never contended (nobody else submits here), and the
// validation layer (thread-safety and synchronization checks) reports nothing; likewise without a lock of the
// application's.
TEST_F(ContextSharing, TwoContextsOnOneApplicationDeviceShareItsQueue) {
  const RunResult& want = alone();
  const auto& renders = renders_alone();
  for (const bool app_lock : {true, false}) {
    SCOPED_TRACE(app_lock ? "with the application's queue lock" : "without a queue lock");
    test::AppDevice app;
    HostDevice host = app.host();
    std::mutex queue_mutex;
    std::atomic<int> locks{0}, contended{0};
    if (app_lock) {
      host.lock_queue = [&] {
        if (!queue_mutex.try_lock()) {
          ++contended;
          queue_mutex.lock();
        }
        ++locks;
      };
      host.unlock_queue = [&] { queue_mutex.unlock(); };
    } else {
      host.lock_queue = host.unlock_queue = {};
    }
    ContextOptions co;
    co.pipeline_cache_file = "-";
    {
      Context ctx(host, co), preview(host, co);
      auto scene = scene_on(preview);
      HeldJob held(ctx);
      Job& job = held.job;
      RunResult& r = held.result;
      for (int i = 0; i < 4; ++i) ASSERT_EQ(render(*scene, i), renders[size_t(i % 2)]) << "render " << i;
      held.release();
      for (int i = 0; job.poll() == JobState::running; ++i) ASSERT_EQ(render(*scene, i), renders[size_t(i % 2)]);
      ASSERT_EQ(job.poll(), JobState::succeeded) << job.error();
      EXPECT_EQ(r.latent, want.latent);
    }
    EXPECT_EQ(contended.load(), 0) << "two dvs submissions took the application's queue lock at once";
    if (app_lock) {
      EXPECT_GT(locks.load(), 0);
    }
    EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
  }
}

// The context destroyed while a scene made on it lives (the render aborted in vkResetDescriptorPool): the scene keeps
// the device objects and renders its own image; they go with it.
TEST_F(ContextSharing, ASceneOutlivesItsContext) {
  auto ctx = std::make_unique<Context>();
  auto scene = scene_on(*ctx);
  ctx.reset();
  EXPECT_EQ(render(*scene, 0), renders_alone()[0]);
  EXPECT_EQ(render(*scene, 1), renders_alone()[1]);
  scene.reset();
}

// The context destroyed under a running job (a segfault): the destructor cancels the job and returns once it has
// ended; its result is dvs::Cancelled.
TEST_F(ContextSharing, DestroyingTheContextCancelsItsJobAndWaitsForItsEnd) {
  auto ctx = std::make_unique<Context>();
  Latch started;
  RunResult r(latent_shape());
  Job job = start_pipeline(*ctx, options(), clip(), views(r), [&](const std::string&, int, int, const std::string&) {
    started.open();
  });
  started.wait();
  ctx.reset();
  EXPECT_EQ(job.poll(), JobState::cancelled) << "the context's destructor returned before its job ended";
  EXPECT_THROW(job.run_report(), Cancelled);
}

// A scene destroyed while a job holds its context cannot be refused (a destructor): it returns at once, also while
// the job waits in its progress callback (a destructor waiting for the job would hang here), and the scene's device
// objects are freed at the job's end, on the job's thread, never beside the job's own use of the context (the other
// scenes are destroyed while it works); the job is not disturbed.
TEST_F(ContextSharing, ScenesDestroyedUnderAJobAreFreedAtTheJobsEnd) {
  const RunResult& want = alone();
  ContextOptions validated;  // the layer's thread-safety checks see a command pool used by two threads at once
  validated.validation = true;
  validated.pipeline_cache_file = "-";
  Context ctx(validated);
  std::vector<std::unique_ptr<PointCloudScene>> scenes;
  for (int i = 0; i < 12; ++i) scenes.push_back(scene_on(ctx));
  for (auto& s : scenes) render(*s, 1);  // each with its recordings and packed image
  HeldJob held(ctx);
  Job& job = held.job;
  RunResult& r = held.result;
  // The job waits in its callback: the device memory in use holds still but for what the destructor frees now.
  const uint64_t in_use = ctx.internal().allocator().stats().bytes_in_use;
  scenes.back().reset();  // returns while the job waits in its callback
  scenes.pop_back();
  EXPECT_EQ(job.poll(), JobState::running);
  EXPECT_EQ(ctx.internal().allocator().stats().bytes_in_use, in_use)
      << "the scene's device memory was freed beside the job, not at its end";
  held.release();
  int while_running = 0;
  for (auto& s : scenes) {
    s.reset();
    if (job.poll() == JobState::running) ++while_running;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  job.wait();
  ASSERT_EQ(job.poll(), JobState::succeeded) << job.error();
  EXPECT_GT(while_running, 0) << "no scene was destroyed while the job worked";
  EXPECT_EQ(r.latent, want.latent);
  EXPECT_LT(ctx.internal().allocator().stats().bytes_in_use, in_use) << "the scenes' device memory was never freed";
  auto again = scene_on(ctx);  // the context is free again
  EXPECT_EQ(render(*again, 0), renders_alone()[0]);
  const auto messages = ctx.internal().validation_messages();
  EXPECT_TRUE(messages.empty()) << messages.size() << " validation message(s), first: " << messages[0];
}

// Error kinds (issue 34 §2.9, §2.10): told apart without reading the message, and nothing but a dvs::Error escapes.
TEST_F(ContextSharing, ErrorsSayTheirKind) {
  Context ctx;
  auto scene = scene_on(ctx);
  Pose column_major;
  column_major.m[12] = 0.1;  // a translation where the bottom row is
  std::vector<uint8_t> rgba(size_t(H) * W * 4);
  EXPECT_EQ(error_of([&] { scene->render(column_major, HostView{rgba.data(), ElementType::u8, {H, W, 4}}); }).first,
            ErrorKind::invalid_argument);
  const auto [wait_kind, wait_message] = error_of([&] { ctx.wait(ctx.submitted_value() + 5); });
  EXPECT_EQ(wait_kind, ErrorKind::invalid_argument) << wait_message;
  // A shape no host can hold (2^20 x 2^20): a dvs::Error, not std::bad_alloc.
  const std::vector<float> small(16);
  const auto [huge_kind, huge_message] = error_of([&] {
    PointCloudScene s(ctx, ConstHostView{small.data(), ElementType::f32, {3, 1 << 20, 1 << 20}},
                      ConstHostView{small.data(), ElementType::f32, {1 << 20, 1 << 20}},
                      CameraIntrinsics::dvs_default(1 << 20, 1 << 20));
  });
  EXPECT_EQ(huge_kind, ErrorKind::out_of_memory) << huge_message;
  EXPECT_NE(huge_message.find("dvs::PointCloudScene"), std::string::npos) << huge_message;
  // The first real cause of a clip the model cannot take, before the latent's size.
  RunResult r(latent_shape());
  ClipView eight = clip();
  eight.frames.shape[0] = 8;
  eight.depth.shape[0] = 8;
  ClipResultViews v = views(r);
  v.output.shape[0] = 8;
  const auto [frames_kind, frames_message] = error_of([&] { run_pipeline(ctx, options(), eight, v); });
  EXPECT_EQ(frames_kind, ErrorKind::invalid_argument);
  EXPECT_NE(frames_message.find("8 is not 4k+1"), std::string::npos) << frames_message;
  RunOptions fancy = options();
  fancy.preset = "fancy";
  const auto [preset_kind, preset_message] = error_of([&] { run_pipeline(ctx, fancy, clip(), views(r)); });
  EXPECT_EQ(preset_kind, ErrorKind::invalid_argument);
  EXPECT_NE(preset_message.find("fancy"), std::string::npos) << preset_message;
  RunOptions no_model = options();
  no_model.model = in->dir / "no-such-model";
  EXPECT_EQ(error_of([&] { run_pipeline(ctx, no_model, clip(), views(r)); }).first, ErrorKind::input);
  EXPECT_EQ(Cancelled().kind(), ErrorKind::cancelled);
}

}  // namespace
}  // namespace dvs
