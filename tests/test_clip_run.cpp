// dvs::run_pipeline on a clip in memory (dvs/clip_run.hpp), on the tiny random model and the 9-frame scene of
// tests/support/pipeline_inputs.hpp. The reference is `dvs run` on files: the same clip as a video and a depth file
// gives the same sampled latent byte for byte (the file run leaves it in its latent cache), the same render and mask
// as `dvs render --save-npy`, and its output.mp4 decodes to the in-memory output within the codec's error. Then:
// explicit poses equal to the named preset's sample the same latent and other poses another; a second identical run
// reuses the cached latent; every refused option or view names itself; the run works on an application's device
// and leaves it usable; the job form gives the same latent and can be cancelled.
//
// One file run and one memory run are shared by every test (SetUpTestSuite); the others add a few runs of a few
// seconds each on lavapipe.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <memory>
#include <thread>

#include "dvs/cache.hpp"
#include "dvs/clip_run.hpp"
#include "dvs/error.hpp"
#include "dvs/trajectory.hpp"
#include "dvs/video.hpp"
#include "geometry/trajectory.hpp"
#include "io/depth.hpp"
#include "io/npy.hpp"
#include "io/video.hpp"
#include "pipeline/clip_input.hpp"
#include "support/app_device.hpp"
#include "support/expect_error.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"
#include "vk/context.hpp"
#include "vk/device_info.hpp"

namespace dvs {
namespace {

constexpr int F = 9, H = 64, W = 64;

// Memory for one run's results, and the views onto it.
struct Results {
  std::vector<uint8_t> output = std::vector<uint8_t>(size_t(F) * H * W * 3);
  std::vector<float> render = std::vector<float>(size_t(F) * 3 * H * W);
  std::vector<float> mask = std::vector<float>(size_t(F) * H * W);
  std::vector<int64_t> latent_shape;
  std::vector<float> latent;
  RunReport report;
  explicit Results(std::vector<int64_t> shape) : latent_shape(std::move(shape)) {
    latent.resize(size_t(latent_shape[0] * latent_shape[1] * latent_shape[2] * latent_shape[3]));
  }
  ClipResultViews views() {
    ClipResultViews v;
    v.output = {output.data(), ElementType::u8, {F, H, W, 3}};
    v.render = {render.data(), ElementType::f32, {F, 3, H, W}};
    v.mask = {mask.data(), ElementType::f32, {F, H, W}};
    v.latent = {latent.data(), ElementType::f32, latent_shape};
    return v;
  }
};

bool same_bytes(const std::vector<float>& a, const HostTensor& b) {
  return a.size() * sizeof(float) == b.bytes() && std::memcmp(a.data(), b.data.data(), b.bytes()) == 0;
}

// What every test shares: the inputs, the frames as dvs decodes them, the context, one memory run (ClipRun::memory).
struct Shared {
  test::PipelineInputs in;
  std::unique_ptr<Context> ctx;
  VideoFrames frames;      // the video decoded by dvs's own reader at the working size
  HostTensor depth;        // the depth file's values
  std::unique_ptr<Results> memory;
  std::vector<std::string> memory_stages;
};
Shared* shared = nullptr;

class ClipRun : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    shared = new Shared;
    Shared& s = *shared;
    ContextOptions co;
    co.validation = true;
    co.pipeline_cache_file = "-";
    s.ctx = std::make_unique<Context>(co);
    s.frames = read_video_frames(s.in.video, 0, F, H, W);
    s.depth = read_npy(s.in.depth);
  }
  // The in-memory run the tests compare with, made by the first test of this process that asks for it (ctest runs
  // each test in a process of its own: only those that need it pay for it).
  static Results& memory() {
    Shared& s = *shared;
    if (!s.memory) {
      s.memory = std::make_unique<Results>(latent_shape());
      s.memory->report = run(clip(), options(s.in.dir / "memory_cache"), *s.memory, &s.memory_stages);
    }
    return *s.memory;
  }
  static void TearDownTestSuite() {
    delete shared;
    shared = nullptr;
  }
  void SetUp() override { shared->ctx->internal().clear_validation_messages(); }
  void TearDown() override {
    const auto msgs = shared->ctx->internal().validation_messages();
    EXPECT_TRUE(msgs.empty()) << msgs.size() << " validation message(s), first: " << (msgs.empty() ? "" : msgs[0]);
  }

  static std::vector<int64_t> latent_shape() { return clip_latent_shape(shared->in.model, F, H, W); }
  // The file run's options with the files taken out: the clip replaces them.
  static RunOptions options(const std::filesystem::path& cache) {
    RunOptions o = shared->in.run_options({}, cache);
    o.render.video.clear();
    o.render.depth.clear();
    o.render.out_dir.clear();
    return o;
  }
  static ClipView clip() {
    ClipView c;
    c.frames = {shared->frames.rgb.data(), ElementType::u8, {F, H, W, 3}};
    c.depth = {shared->depth.data.data(), ElementType::f32, {F, H, W}};
    return c;
  }
  static RunReport run(const ClipView& c, const RunOptions& o, Results& r, std::vector<std::string>* stages = nullptr,
                       Context* ctx = nullptr) {
    return run_pipeline(ctx ? *ctx : *shared->ctx, o, c, r.views(), [stages](const std::string& stage, int, int, const std::string&) {
      if (stages && (stages->empty() || stages->back() != stage)) stages->push_back(stage);
    });
  }
  // The poses of a named path for this clip, as `dvs render` builds them (the radius from the centre depth).
  static std::vector<Pose> preset_poses(const std::string& name) {
    DepthOptions d;
    d.values = DepthValues::depth;
    return load_trajectory(name, F, geometry::official_radius(centre_depth(depth_from_array(shared->depth, "depth", d))));
  }
};

// (a) The key test: files and memory give the same numbers.
TEST_F(ClipRun, SamplesTheLatentTheFileRunSamplesAndRendersWhatDvsRenderRenders) {
  Shared& s = *shared;
  // The reference: `dvs run` on the files (run_pipeline with file options), its latent from its own cache.
  run_pipeline(s.in.run_options(s.in.dir / "file", s.in.dir / "file_cache"));
  HostTensor file_latent;
  for (const auto& name : test::files_in(cache_folder(s.in.dir / "file_cache")))
    if (name.rfind("latent-", 0) == 0 && name.size() > 4 && name.substr(name.size() - 4) == ".npy")
      file_latent = read_npy(cache_folder(s.in.dir / "file_cache") / name);
  ASSERT_EQ(file_latent.shape, latent_shape()) << "the file run left no latent in its cache";
  EXPECT_TRUE(same_bytes(memory().latent, file_latent)) << "the in-memory run sampled another latent";

  const test::TempDir dir;
  const auto r = test::run_command(test::program("dvs") + " render --video " + s.in.video.string() + " --depth " +
                                   s.in.depth.string() + " --metric-depth --size 64x64 --frames 9 --no-glb --save-npy --out " +
                                   (dir / "out").string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(same_bytes(memory().render, read_npy(dir / "out" / "render.npy"))) << "render";
  EXPECT_TRUE(same_bytes(memory().mask, read_npy(dir / "out" / "mask.npy"))) << "mask";

  // The new view: output.mp4 is the file run's output through H.264, which is far from lossless on the tiny random
  // model's noisy frames. The same encoder (deterministic: see Jobs.APipelineJobWritesWhatTheBlockingRunWrites) fed
  // the in-memory output writes the same bytes: the u8 frames are the file run's exactly (the writer's rounding
  // gives back each level, unit_to_level(level_to_unit(v)) = v).
  write_video(dir / "memory.mp4", frames_from_levels(memory().output.data(), F, H, W), 10.0);
  const std::string mp4 = test::read_text(s.in.dir / "file" / "output.mp4");
  EXPECT_GT(mp4.size(), 1000u);
  EXPECT_EQ(test::read_text(dir / "memory.mp4"), mp4) << "the in-memory output encodes to other bytes than output.mp4";

  const RunReport& rep = memory().report;
  EXPECT_FALSE(rep.inversion_from_cache);
  EXPECT_TRUE(rep.output_mp4.empty() && rep.render_mp4.empty() && rep.mask_mp4.empty() && rep.comparison_mp4.empty() &&
              rep.run_json.empty());
  EXPECT_GT(rep.peak_device_bytes, 0u);
  for (const char* stage : {"render", "encode", "invert", "sample", "decode", "write"})
    EXPECT_NE(std::find(s.memory_stages.begin(), s.memory_stages.end(), stage), s.memory_stages.end()) << stage;
}

// The f32 forms of the frames and results: the same latent, and the output the u8 form rounds.
TEST_F(ClipRun, FloatFramesAndResultsMatchTheLevelForms) {
  Shared& s = *shared;
  HostTensor rgb = frames_from_levels(s.frames.rgb.data(), F, H, W);
  ClipView c = clip();
  c.frames = {rgb.data.data(), ElementType::f32, {F, 3, H, W}};
  Results r(latent_shape());
  std::vector<float> output(size_t(F) * 3 * H * W);
  ClipResultViews v = r.views();
  v.output = {output.data(), ElementType::f32, {F, 3, H, W}};
  v.render = {};  // optional views may be left out
  v.mask = {};
  run_pipeline(*s.ctx, options(s.in.dir / "memory_cache"), c, v);
  EXPECT_EQ(r.latent, memory().latent);
  const int64_t plane = H * W;
  for (int64_t f = 0; f < F; ++f)
    for (int64_t i = 0; i < plane; ++i)
      for (int64_t ch = 0; ch < 3; ++ch) {
        const float x = output[size_t((f * 3 + ch) * plane + i)];
        ASSERT_EQ(memory().output[size_t((f * plane + i) * 3 + ch)], uint8_t(std::lround(std::clamp((x + 1) * 127.5f, 0.0f, 255.0f))));
      }
}

// A second identical run finds the sampled latent in the cache (keyed by the clip's bytes) and skips to the decode.
TEST_F(ClipRun, ASecondIdenticalRunReusesTheCachedLatent) {
  Shared& s = *shared;
  memory();  // the first run, which fills memory_cache
  Results r(latent_shape());
  std::vector<std::string> stages;
  run(clip(), options(s.in.dir / "memory_cache"), r, &stages);
  EXPECT_NE(std::find(stages.begin(), stages.end(), "latent"), stages.end()) << "the latent was not reused";
  EXPECT_EQ(std::find(stages.begin(), stages.end(), "sample"), stages.end()) << "the run sampled again";
  EXPECT_EQ(r.latent, memory().latent);
  EXPECT_EQ(r.output, memory().output);
  // Other frames, depth or poses are another clip: the cache does not hand them this latent.
  std::vector<uint8_t> other_frames = s.frames.rgb;
  other_frames[777] ^= 1;
  HostTensor deeper = s.depth;
  deeper.as<float>()[555] *= 1.0f + 1e-6f;
  const std::vector<glm::dmat4> identity(F, glm::dmat4(1.0));
  std::vector<glm::dmat4> moved = identity;
  moved[4][3][0] += 1e-12;  // frame 4's x translation
  auto key = [&](const std::vector<uint8_t>& f, const HostTensor& d, const std::optional<std::vector<glm::dmat4>>& p) {
    return clip_input_key(f.data(), f.size(), "u8", d, p, "loop1");
  };
  const auto base = key(s.frames.rgb, s.depth, std::nullopt);
  EXPECT_NE(key(other_frames, s.depth, std::nullopt), base) << "one level of one pixel";
  EXPECT_NE(key(s.frames.rgb, deeper, std::nullopt), base) << "one depth value's last bits";
  EXPECT_NE(key(s.frames.rgb, s.depth, identity), base) << "poses given";
  EXPECT_NE(key(s.frames.rgb, s.depth, moved), key(s.frames.rgb, s.depth, identity)) << "a pose moved by 1e-12";
  EXPECT_EQ(key(s.frames.rgb, s.depth, identity), key(s.frames.rgb, s.depth, identity));
}

// (b) Poses handed over equal to the named preset's sample the same latent; other poses another.
TEST_F(ClipRun, GivenPosesEqualToThePresetSampleTheSameLatentAndOthersAnother) {
  Shared& s = *shared;
  ClipView c = clip();
  c.poses = preset_poses(options({}).render.trajectory);
  Results same(latent_shape());
  run(c, options(s.in.dir / "poses_cache"), same);
  EXPECT_EQ(same.latent, memory().latent);
  EXPECT_EQ(same.mask, memory().mask);
  c.poses = preset_poses("pan_left:10");
  Results other(latent_shape());
  run(c, options(s.in.dir / "poses_cache"), other);
  EXPECT_NE(other.latent, memory().latent);
  EXPECT_NE(other.mask, memory().mask);
}

// (c) Every refused option or view, each before any work, naming itself.
TEST_F(ClipRun, RefusedOptionsAndViewsNameThemselves) {
  Shared& s = *shared;
  struct Case {
    std::string what;
    std::function<void(RunOptions&, ClipView&, ClipResultViews&)> change;
  };
  std::vector<float> nan_depth(s.depth.as<float>(), s.depth.as<float>() + s.depth.numel());
  nan_depth[100] = NAN;
  std::vector<float> zero_depth(nan_depth.size(), 0.0f);
  std::vector<float> small(16);
  const std::vector<Case> cases = {
      {"RunOptions::render.video", [](RunOptions& o, ClipView&, ClipResultViews&) { o.render.video = "a.mp4"; }},
      {"RunOptions::render.depth", [](RunOptions& o, ClipView&, ClipResultViews&) { o.render.depth = "d.npy"; }},
      {"RunOptions::render.depth_model", [](RunOptions& o, ClipView&, ClipResultViews&) { o.render.depth_model = "v.pth"; }},
      {"RunOptions::render.out_dir", [](RunOptions& o, ClipView&, ClipResultViews&) { o.render.out_dir = "out"; }},
      {"RunOptions::render.height/width", [](RunOptions& o, ClipView&, ClipResultViews&) { o.render.height = 72; }},
      {"RunOptions::render.frames", [](RunOptions& o, ClipView&, ClipResultViews&) { o.render.frames = 5; }},
      {"4k+1", [](RunOptions&, ClipView& c, ClipResultViews&) { c.frames.shape = {8, H, W, 3}; }},
      {"multiples of 8", [](RunOptions&, ClipView& c, ClipResultViews&) { c.frames.shape = {F, 60, 64, 3}; }},
      {"ClipView::frames", [](RunOptions&, ClipView& c, ClipResultViews&) { c.frames.type = ElementType::f32; }},
      {"ClipView::frames", [](RunOptions&, ClipView& c, ClipResultViews&) { c.frames.data = nullptr; }},
      {"ClipView::depth", [](RunOptions&, ClipView& c, ClipResultViews&) { c.depth.shape = {F, H, W, 1}; }},
      {"ClipView::depth", [](RunOptions&, ClipView& c, ClipResultViews&) { c.depth.type = ElementType::u8; }},
      {"ClipView::depth", [&](RunOptions&, ClipView& c, ClipResultViews&) { c.depth.data = nan_depth.data(); }},
      {"ClipView::depth", [&](RunOptions&, ClipView& c, ClipResultViews&) { c.depth.data = zero_depth.data(); }},
      {"ClipView::poses", [](RunOptions&, ClipView& c, ClipResultViews&) { c.poses.resize(3); }},
      {"ClipView::poses[2]", [](RunOptions&, ClipView& c, ClipResultViews&) {
         c.poses.resize(F);
         c.poses[2].m[12] = 1;
       }},
      {"ClipResultViews::output", [](RunOptions&, ClipView&, ClipResultViews& v) { v.output.data = nullptr; }},
      {"ClipResultViews::output", [](RunOptions&, ClipView&, ClipResultViews& v) { v.output.shape = {F, W, H, 4}; }},
      {"ClipResultViews::render", [](RunOptions&, ClipView&, ClipResultViews& v) { v.render.shape = {F, H, W}; }},
      {"ClipResultViews::mask", [](RunOptions&, ClipView&, ClipResultViews& v) { v.mask.shape = {F, 1, H, W}; }},
      {"ClipResultViews::latent", [&](RunOptions&, ClipView&, ClipResultViews& v) { v.latent.shape = {4, 4}; }},
      // The preflight still checks what the clip does not replace: the model, the trajectory, the settings.
      {"no such model folder", [&](RunOptions& o, ClipView&, ClipResultViews& v) {
         o.model = s.in.dir / "no-model";
         v.latent = {};
       }},
      {"RunOptions::render.trajectory", [](RunOptions& o, ClipView&, ClipResultViews&) { o.render.trajectory = "no_such_path"; }},
      {"preset", [](RunOptions& o, ClipView&, ClipResultViews&) { o.preset = "fast"; }},
  };
  for (const Case& k : cases) {
    RunOptions o = options(s.in.dir / "refused_cache");
    ClipView c = clip();
    Results r(latent_shape());
    ClipResultViews v = r.views();
    k.change(o, c, v);
    std::vector<std::string> stages;
    test::expect_error([&] {
      run_pipeline(*s.ctx, o, c, v, [&](const std::string& stage, int, int, const std::string&) { stages.push_back(stage); });
    }, {k.what});
    EXPECT_TRUE(stages.empty()) << k.what << ": refused after work began (" << (stages.empty() ? "" : stages[0]) << ")";
  }
  EXPECT_FALSE(std::filesystem::exists(s.in.dir / "refused_cache")) << "a refused run wrote to the cache";
}

// (d) The application's device: the test application of support/app_device.hpp (the validation layer with
// synchronization validation across submissions, a queue lock, a buffer of its own) hands its objects over; the run
// samples the same latent, and afterwards the application's buffer holds what it held and its device and queue still
// take its own work.
TEST_F(ClipRun, RunsOnTheApplicationsDeviceAndLeavesItsObjectsAsTheyWere) {
  Shared& s = *shared;
  test::AppDevice app;
  test::AppDevice::Buffer& mine = app.buffer(4096);  // the application's own buffer, with a pattern it checks after
  auto* words = static_cast<uint32_t*>(mine.data);
  for (uint32_t i = 0; i < 1024; ++i) words[i] = 0x9e3779b9u * (i + 1);
  Results r(latent_shape());
  {
    ContextOptions co;
    co.pipeline_cache_file = "-";
    Context ctx(app.host(), co);
    EXPECT_FALSE(ctx.owns_device());
    run(clip(), options(s.in.dir / "host_cache"), r, nullptr, &ctx);
  }
  EXPECT_EQ(r.latent, memory().latent) << "another latent on the application's device";
  for (uint32_t i = 0; i < 1024; ++i) ASSERT_EQ(words[i], 0x9e3779b9u * (i + 1)) << "the application's buffer, word " << i;
  // Its device and queue still take work: an empty submission signals its fence.
  VkFenceCreateInfo fci{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  VkFence fence = VK_NULL_HANDLE;
  ASSERT_EQ(vkCreateFence(app.device, &fci, nullptr, &fence), VK_SUCCESS);
  EXPECT_EQ(vkQueueSubmit(app.queue, 0, nullptr, fence), VK_SUCCESS);
  EXPECT_EQ(vkWaitForFences(app.device, 1, &fence, VK_TRUE, UINT64_MAX), VK_SUCCESS);
  vkDestroyFence(app.device, fence, nullptr);
  EXPECT_EQ(vkDeviceWaitIdle(app.device), VK_SUCCESS);
  EXPECT_EQ(app.locks, app.unlocks);
  EXPECT_GT(app.locks, 0) << "dvs submitted without the application's queue lock";
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

// (d') The clip and the results in the application's device buffers (ClipDeviceView, ClipResultDeviceViews): the same
// numbers as the run on host views, the results in its buffers when the call returns (and when its job ends), and
// wrong buffers named before any work.
TEST_F(ClipRun, TakesAndGivesTheApplicationsDeviceBuffers) {
  Shared& s = *shared;
  const Results& want = memory();
  test::AppDevice app;
  const size_t pixels = size_t(F) * H * W;
  test::AppDevice::Buffer &frames = app.buffer(pixels * 3), &depth = app.buffer(pixels * 4);
  test::AppDevice::Buffer &output = app.buffer(pixels * 3), &render = app.buffer(pixels * 3 * 4),
                          &mask = app.buffer(pixels * 4), &latent = app.buffer(want.latent.size() * 4);
  std::memcpy(frames.data, s.frames.rgb.data(), pixels * 3);
  std::memcpy(depth.data, s.depth.data.data(), pixels * 4);
  ClipDeviceView clip;
  clip.frames = {frames.buffer, 0, ElementType::u8, {F, H, W, 3}};
  clip.depth = {depth.buffer, 0, ElementType::f32, {F, H, W}};
  ClipResultDeviceViews out;
  out.output = {output.buffer, 0, ElementType::u8, {F, H, W, 3}};
  out.render = {render.buffer, 0, ElementType::f32, {F, 3, H, W}};
  out.mask = {mask.buffer, 0, ElementType::f32, {F, H, W}};
  out.latent = {latent.buffer, 0, ElementType::f32, want.latent_shape};
  auto same = [](const test::AppDevice::Buffer& b, const auto& v) {
    return std::memcmp(b.data, v.data(), v.size() * sizeof(v[0])) == 0;
  };
  {
    ContextOptions co;
    co.pipeline_cache_file = "-";
    Context ctx(app.host(), co);
    const RunOptions o = options(s.in.dir / "device_cache");
    // Refused before any work, each naming the buffer: no progress event, nothing in the cache.
    struct Case {
      std::string what, detail;
      std::function<void(ClipDeviceView&, ClipResultDeviceViews&)> spoil;
    };
    test::AppDevice::Buffer& small = app.buffer(64);
    const std::vector<Case> cases{
        {"ClipDeviceView::frames", "holds at most", [&](ClipDeviceView& c, ClipResultDeviceViews&) { c.frames.buffer = small.buffer; }},
        {"ClipDeviceView::depth", "multiple of 4", [](ClipDeviceView& c, ClipResultDeviceViews&) { c.depth.offset = 2; }},
        {"ClipResultDeviceViews::output", "VK_NULL_HANDLE", [](ClipDeviceView&, ClipResultDeviceViews& r) { r.output.buffer = VK_NULL_HANDLE; }},
        {"ClipResultDeviceViews::latent", "holds at most", [&](ClipDeviceView&, ClipResultDeviceViews& r) { r.latent.buffer = small.buffer; }},
        {"ClipResultDeviceViews::mask", "expected f32", [](ClipDeviceView&, ClipResultDeviceViews& r) { r.mask.shape = {F, H, W, 1}; }},
    };
    for (const Case& k : cases) {
      ClipDeviceView c = clip;
      ClipResultDeviceViews r = out;
      k.spoil(c, r);
      std::vector<std::string> stages;
      test::expect_error([&] {
        run_pipeline(ctx, o, c, r, [&](const std::string& stage, int, int, const std::string&) { stages.push_back(stage); });
      }, {k.what, k.detail});
      EXPECT_TRUE(stages.empty()) << k.what << ": refused after work began";
    }
    EXPECT_FALSE(std::filesystem::exists(s.in.dir / "device_cache")) << "a refused run wrote to the cache";

    run_pipeline(ctx, o, clip, out);  // the results are in the buffers when it returns
    EXPECT_TRUE(same(output, want.output)) << "the output differs from the run on host views";
    EXPECT_TRUE(same(render, want.render)) << "the render differs";
    EXPECT_TRUE(same(mask, want.mask)) << "the mask differs";
    EXPECT_TRUE(same(latent, want.latent)) << "the latent differs";

    // The job form (the latent now from the cache), into cleared buffers.
    for (auto* b : {&output, &render, &mask, &latent}) std::memset(b->data, 0, 64);
    Job job = start_pipeline(ctx, o, clip, out);
    ASSERT_TRUE(job.wait_for(std::chrono::minutes(10)));
    ASSERT_EQ(job.poll(), JobState::succeeded) << job.error();
    EXPECT_TRUE(same(output, want.output) && same(render, want.render) && same(mask, want.mask) && same(latent, want.latent))
        << "the job's results differ";
  }
  EXPECT_EQ(app.locks, app.unlocks);
  EXPECT_TRUE(app.messages.empty()) << app.messages.size() << " validation message(s): " << app.first_message();
}

// (e) The job form: the same latent; cancelling stops it.
TEST_F(ClipRun, TheJobGivesTheSameLatentAndCanBeCancelled) {
  Shared& s = *shared;
  RunOptions o = options({});
  o.use_cache = false;  // sampled again, not read back
  Results r(latent_shape());
  Job job = start_pipeline(*s.ctx, o, clip(), r.views());
  ASSERT_TRUE(job.wait_for(std::chrono::minutes(10)));
  ASSERT_EQ(job.poll(), JobState::succeeded) << job.error();
  EXPECT_FALSE(job.run_report().inversion_from_cache);
  EXPECT_EQ(r.latent, memory().latent);
  EXPECT_EQ(r.output, memory().output);

  std::atomic<int> events{0};
  Results c(latent_shape());
  Job cancelled = start_pipeline(*s.ctx, o, clip(), c.views(), [&](const std::string&, int, int, const std::string&) { ++events; });
  while (events == 0 && cancelled.poll() == JobState::running) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  cancelled.cancel();
  cancelled.wait();
  EXPECT_EQ(cancelled.poll(), JobState::cancelled) << cancelled.error();
  EXPECT_THROW(cancelled.run_report(), Cancelled);
}

}  // namespace
}  // namespace dvs
