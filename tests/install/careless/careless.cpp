// The installed C++ library under careless use (issue 34 §2): built against the installed package by
// tests/install/run_install_test.sh, run with the conformance pack's tiny model. Each check prints "ok ..." or
// "FAIL ..."; exit status 0 = all passed. tests/test_context_sharing.cpp checks the same rules in more depth (an
// application's device, the timing of each overlap) in the build tree.
//
//   careless MODEL_DIR CACHE_DIR
//
// The compile itself is a check: the version macros, dvs::ErrorKind, and ConstHostView on const memory for inputs.
#include <dvs/clip_run.hpp>
#include <dvs/context.hpp>
#include <dvs/error.hpp>
#include <dvs/info.hpp>
#include <dvs/scene.hpp>

#include <atomic>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>
#include <vector>

static_assert(DVS_VERSION_MAJOR >= 0 && DVS_VERSION_MINOR >= 0 && DVS_VERSION_PATCH >= 0, "the version macros");

namespace {

constexpr int F = 9, H = 64, W = 64;
int failures = 0;

void check(bool ok, const std::string& what) {
  std::printf("%s %s\n", ok ? "ok" : "FAIL", what.c_str());
  if (!ok) ++failures;
}

// The clip: frames with a value per pixel, channel and frame; metric depth of a tilted plane 2..3 units away. Const:
// inputs take const memory.
const std::vector<uint8_t> frames = [] {
  std::vector<uint8_t> v(size_t(F) * H * W * 3);
  for (size_t i = 0; i < v.size(); ++i) v[i] = uint8_t((i * 7 + i / 192 * 11) % 256);
  return v;
}();
const std::vector<float> depth = [] {
  std::vector<float> v(size_t(F) * H * W);
  for (int f = 0; f < F; ++f)
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) v[(size_t(f) * H + y) * W + x] = 2.0f + 0.5f * float(x + y) / (W + H) + 0.01f * f;
  return v;
}();

std::string model_dir, cache_dir;

dvs::RunOptions options() {
  dvs::RunOptions o;
  o.model = model_dir;
  o.prompt = "a red fox";
  o.steps = 4, o.inversion_steps = 3;
  o.render.height = H, o.render.width = W, o.render.frames = 0, o.render.metric_depth = true;
  o.cache_dir = cache_dir;
  o.use_cache = false;
  return o;
}

dvs::ClipView clip() {
  dvs::ClipView c;
  c.frames = {frames.data(), dvs::ElementType::u8, {F, H, W, 3}};
  c.depth = {depth.data(), dvs::ElementType::f32, {F, H, W}};
  return c;
}

struct Output {
  std::vector<uint8_t> rgb = std::vector<uint8_t>(size_t(F) * H * W * 3);
  dvs::ClipResultViews views() {
    dvs::ClipResultViews v;
    v.output = {rgb.data(), dvs::ElementType::u8, {F, H, W, 3}};
    return v;
  }
};

// A job on `ctx` whose first progress event waits until release() (so "while the job runs" is certain); made, it is
// waiting there.
struct HeldJob {
  std::atomic<bool> started{false}, released{false};
  Output out;
  dvs::Job job;
  explicit HeldJob(dvs::Context& ctx)
      : job(dvs::start_pipeline(ctx, options(), clip(), out.views(), [this](const std::string&, int, int, const std::string&) {
          started = true;
          while (!released) std::this_thread::yield();
        })) {
    while (!started) std::this_thread::yield();
  }
  void release() { released = true; }
};

std::unique_ptr<dvs::PointCloudScene> scene_on(dvs::Context& ctx) {
  dvs::SceneOptions so;
  so.depth_is_disparity = false;
  return std::make_unique<dvs::PointCloudScene>(ctx, dvs::ConstHostView{frames.data(), dvs::ElementType::u8, {H, W, 3}},
                                                dvs::ConstHostView{depth.data(), dvs::ElementType::f32, {H, W}},
                                                dvs::CameraIntrinsics::dvs_default(W, H), so);
}

std::vector<uint8_t> render(dvs::PointCloudScene& s, int i) {
  dvs::Pose p;
  p.m[3] = i % 2 ? 0.05 : -0.03;
  std::vector<uint8_t> rgba(size_t(H) * W * 4);
  s.render(p, dvs::HostView{rgba.data(), dvs::ElementType::u8, {H, W, 4}});
  return rgba;
}

// The kind and message of the dvs::Error `f` throws; anything else that escapes is a failure.
template <class Call>
std::pair<dvs::ErrorKind, std::string> error_of(Call&& f) {
  try {
    f();
  } catch (const dvs::Error& e) {
    return {e.kind(), e.what()};
  } catch (const std::exception& e) {
    return {dvs::ErrorKind::internal, std::string("NOT a dvs::Error: ") + e.what()};
  }
  return {dvs::ErrorKind::internal, "no error"};
}

bool has(const std::string& text, const char* part) { return text.find(part) != std::string::npos; }

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: careless MODEL_DIR CACHE_DIR\n");
    return 2;
  }
  model_dir = argv[1], cache_dir = argv[2];
  try {
    char version[32];
    std::snprintf(version, sizeof version, "%d.%d.%d", DVS_VERSION_MAJOR, DVS_VERSION_MINOR, DVS_VERSION_PATCH);
    check(version == std::string(dvs::version()), std::string("version macros ") + version + " = dvs::version() " +
                                                      dvs::version());

    // The references: a run and two renders alone.
    Output alone;
    std::vector<std::vector<uint8_t>> renders;
    {
      dvs::Context ctx;
      dvs::run_pipeline(ctx, options(), clip(), alone.views());
      auto s = scene_on(ctx);
      renders = {render(*s, 0), render(*s, 1)};
    }

    {  // §2.1: two threads on one context (segfaulted): serialised, both right
      dvs::Context ctx;
      Output a, b;
      std::thread other([&] { dvs::run_pipeline(ctx, options(), clip(), a.views()); });
      dvs::run_pipeline(ctx, options(), clip(), b.views());
      other.join();
      check(a.rgb == alone.rgb && b.rgb == alone.rgb, "two threads on one context: both outputs equal the run alone");
    }

    {  // §2.1: a render loop on the job's context (segfaulted): refused, naming the job and the remedy
      dvs::Context ctx;
      auto scene = scene_on(ctx);
      HeldJob held(ctx);
      const auto refused = error_of([&] { render(*scene, 0); });
      held.release();
      held.job.wait();
      check(refused.first == dvs::ErrorKind::invalid_argument && has(refused.second, "pipeline job") &&
                has(refused.second, "second dvs::Context"),
            "a render on the job's context is refused: " + refused.second);
      check(held.job.poll() == dvs::JobState::succeeded && held.out.rgb == alone.rgb,
            "the job is undisturbed: " + held.job.error());
      check(render(*scene, 1) == renders[1], "the scene renders once the job has ended");
    }

    {  // §2.1: the preview on a second context of the same device renders beside the job
      dvs::Context ctx, preview;
      auto scene = scene_on(preview);
      HeldJob held(ctx);
      bool same = true;
      for (int i = 0; i < 6; ++i) same = same && render(*scene, i) == renders[size_t(i % 2)];
      held.release();
      held.job.wait();
      check(same, "six renders on a second context while the job runs equal the renders alone");
      check(held.job.poll() == dvs::JobState::succeeded && held.out.rgb == alone.rgb,
            "the job beside them: " + held.job.error());
    }

    {  // §2.2: the context destroyed first (the render aborted), and under a running job (segfaulted)
      auto ctx = std::make_unique<dvs::Context>();
      auto scene = scene_on(*ctx);
      ctx.reset();
      check(render(*scene, 0) == renders[0], "a scene renders after its context was destroyed");
      ctx = std::make_unique<dvs::Context>();
      std::atomic<bool> started{false};
      Output out;
      dvs::Job job = dvs::start_pipeline(*ctx, options(), clip(), out.views(),
                                         [&](const std::string&, int, int, const std::string&) { started = true; });
      while (!started) std::this_thread::yield();
      ctx.reset();
      check(job.poll() == dvs::JobState::cancelled, "destroying the context cancelled its job and waited for its end");
    }

    {  // §2.9, §2.10: kinds, and nothing but a dvs::Error escapes
      dvs::Context ctx;
      auto scene = scene_on(ctx);
      dvs::Pose column_major;
      column_major.m[12] = 0.1;
      std::vector<uint8_t> rgba(size_t(H) * W * 4);
      const auto pose = error_of([&] { scene->render(column_major, {rgba.data(), dvs::ElementType::u8, {H, W, 4}}); });
      check(pose.first == dvs::ErrorKind::invalid_argument, "a bad pose is invalid_argument: " + pose.second);
      const auto wait = error_of([&] { ctx.wait(ctx.submitted_value() + 1); });
      check(wait.first == dvs::ErrorKind::invalid_argument, "a ticket never submitted is invalid_argument: " + wait.second);
      const std::vector<float> small(16);
      const auto huge = error_of([&] {
        dvs::PointCloudScene s(ctx, {small.data(), dvs::ElementType::f32, {3, 1 << 20, 1 << 20}},
                               {small.data(), dvs::ElementType::f32, {1 << 20, 1 << 20}},
                               dvs::CameraIntrinsics::dvs_default(1 << 20, 1 << 20));
      });
      check(huge.first == dvs::ErrorKind::out_of_memory, "a 2^20 x 2^20 scene is a dvs::Error (out_of_memory): " + huge.second);
    }
  } catch (const std::exception& e) {
    std::printf("FAIL unexpected exception: %s\n", e.what());
    return 1;
  }
  std::printf("%d check(s) failed\n", failures);
  return failures ? 1 : 0;
}
