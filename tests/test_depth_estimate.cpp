// The depth estimate through the library (dvs/depth_estimate.hpp) with a tiny random Video-Depth-Anything model
// (models/random/vda_random, the conformance pack's architecture): progress moves inside one window, a
// cancellation asked from the progress callback stops at the next step, the output is checked before any work,
// dvs depth and --depth-model share one cache entry, a model with NaN weights is an error that caches nothing,
// a long estimate is forecast with the options that make it cheaper, and run's depth stage says when it only
// reads the cache.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>

#include "dvs/depth_estimate.hpp"
#include "dvs/error.hpp"
#include "io/npy.hpp"
#include "io/safetensors_writer.hpp"
#include "models/random/vda_random.hpp"
#include "pipeline/depth_source.hpp"
#include "dvs/duration_text.hpp"
#include "pipeline/job_stages.hpp"
#include "pipeline/stage_tracker.hpp"
#include "spec/vda_config.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/random_vda.hpp"
#include "support/vda_pack.hpp"

namespace dvs {
namespace {

struct Event {
  std::string stage;
  int step = 0, total = 0;
  std::string note;
};

using test::random_vda;

size_t cache_entries(const std::filesystem::path& cache) {
  size_t n = 0;
  std::error_code ec;
  if (std::filesystem::exists(cache))
    for (const auto& e : std::filesystem::recursive_directory_iterator(cache, ec))
      if (e.path().extension() == ".npy") ++n;
  return n;
}

class DepthEstimate : public ::testing::Test {
 protected:
  test::PipelineInputs in;
  DepthJob job() const {
    DepthJob j;
    j.video = in.video;
    j.model = model;
    j.input_size = 28;
    j.frames = 9;
    j.cache_dir = in.cache;
    return j;
  }
  std::filesystem::path model = random_vda(in.dir / "vda");
  std::vector<Event> events;
  ProgressFn record() {
    return [this](const std::string& s, int step, int total, const std::string& note) { events.push_back({s, step, total, note}); };
  }
};

TEST_F(DepthEstimate, ProgressMovesWithinOneWindow) {
  const DepthSummary s = estimate_depth(job(), in.dir / "d.npy", record());
  ASSERT_EQ(s.windows, 1) << "9 frames are one window";
  ASSERT_FALSE(events.empty());
  const VdaConfig cfg = vda_config_from_json(test::vda_model_config(), "pack config");
  // Every encoder block of the window at least, each a step of its own, in order, the last one the window's end.
  EXPECT_GE(events.size(), size_t(cfg.depth)) << "progress only when the window ends";
  int encoder_notes = 0;
  for (size_t i = 0; i < events.size(); ++i) {
    EXPECT_EQ(events[i].stage, "depth");
    EXPECT_EQ(events[i].total, events.front().total);
    EXPECT_EQ(events[i].step, int(i) + 1) << events[i].note;
    encoder_notes += events[i].note.find("encoder block") != std::string::npos;
  }
  EXPECT_EQ(events.back().step, events.back().total);
  EXPECT_GE(encoder_notes, cfg.depth) << "the notes say where in the window the work is";
}

TEST_F(DepthEstimate, CancellationFromTheCallbackStopsAtTheNextStep) {
  bool cancel = false;
  size_t events_when_asked = 0;
  auto progress = [&](const std::string&, int step, int, const std::string&) {
    ++events_when_asked;
    if (step == 2) cancel = true;  // inside the first window, during the encoder
  };
  EXPECT_THROW(estimate_depth(job(), in.dir / "d.npy", progress, [&] { return cancel; }), Cancelled);
  EXPECT_EQ(events_when_asked, 2u) << "steps ran after the cancellation was asked for";
  EXPECT_FALSE(std::filesystem::exists(in.dir / "d.npy"));
  EXPECT_EQ(cache_entries(in.cache), 0u) << "a cancelled estimate was cached";
}

TEST_F(DepthEstimate, OutputIsCheckedBeforeAnyWork) {
  test::write_text(in.dir / "file", "x");
  try {
    estimate_depth(job(), in.dir / "file" / "d.npz", record());
    ADD_FAILURE() << "an --out below a file was accepted";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("is not a folder"), std::string::npos) << m;
    EXPECT_EQ(m.find("disk"), std::string::npos) << "the wrong hint: " << m;
  }
  EXPECT_TRUE(events.empty()) << "the estimate ran before the output was checked";
  EXPECT_EQ(cache_entries(in.cache), 0u);
  // A folder that does not exist yet is made (as dvs run makes --out).
  estimate_depth(job(), in.dir / "new" / "sub" / "d.npz", record());
  EXPECT_TRUE(std::filesystem::is_regular_file(in.dir / "new" / "sub" / "d.npz"));
}

TEST_F(DepthEstimate, DvsDepthAndDepthModelShareTheCache) {
  const DepthSummary first = estimate_depth(job(), in.dir / "a.npy", record());
  EXPECT_FALSE(first.from_cache);
  ASSERT_EQ(cache_entries(in.cache), 1u) << "dvs depth did not fill the depth cache";
  events.clear();
  const DepthSummary again = estimate_depth(job(), in.dir / "b.npz", record());
  EXPECT_TRUE(again.from_cache);
  EXPECT_TRUE(events.empty()) << "a cached estimate was estimated again";
  EXPECT_EQ(read_npy(in.dir / "a.npy").data, read_npy(again.cache_file).data);
  EXPECT_EQ(again.frames, 9);
  EXPECT_EQ(again.windows, 1);
  EXPECT_NE(describe(again).find("1 window:"), std::string::npos) << describe(again);
  // What run/render --depth-model ask for with the same video, model, input size and frames.
  RenderJob r;
  r.video = in.video;
  r.depth_model = model;
  r.depth_input_size = 28;
  r.frames = 9;
  const CachedDepth c = cached_depth(depth_job_for(r, in.cache, false), record());
  EXPECT_TRUE(c.from_cache);
  EXPECT_EQ(c.file, again.cache_file);
  EXPECT_TRUE(events.empty());
}

TEST_F(DepthEstimate, NaNWeightsAreAnErrorAndNothingIsCached) {
  DepthJob j = job();
  j.model = random_vda(in.dir / "nan", "head.scratch.output_conv2.0.weight");  // the ReLU after it hides NaN
  try {
    estimate_depth(j, in.dir / "d.npy", record());
    ADD_FAILURE() << "a model with NaN weights gave a depth";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("head.scratch.output_conv2.0.weight holds NaN"), std::string::npos) << m;
    EXPECT_NE(m.find("dvs-weights inspect --values"), std::string::npos) << "no way to find the others: " << m;
  }
  EXPECT_FALSE(std::filesystem::exists(in.dir / "d.npy"));
  EXPECT_EQ(cache_entries(in.cache), 0u) << "the broken estimate was cached";
}

// Finite weights whose result no sound model gives (here a last bias that the final ReLU turns into 0
// everywhere): the window is refused, nothing is cached.
TEST_F(DepthEstimate, AFlatDisparityIsRefusedAndNotCached) {
  DepthJob j = job();
  j.model = random_vda(in.dir / "flat", "", {{"head.scratch.output_conv2.2.bias", -1e30f}});
  try {
    estimate_depth(j, in.dir / "d.npy", record());
    ADD_FAILURE() << "an all-zero disparity was accepted";
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("depth window 1/1 (clip frames 1-9): the model's disparity is 0"), std::string::npos) << m;
    EXPECT_NE(m.find("not cached"), std::string::npos) << m;
  }
  EXPECT_FALSE(std::filesystem::exists(in.dir / "d.npy"));
  EXPECT_EQ(cache_entries(in.cache), 0u);
}

TEST_F(DepthEstimate, ALongEstimateIsForecastWithWhatMakesItCheaper) {
  DepthJob j = job();
  j.forecast_after_s = 0;  // every estimate is "long"
  std::vector<std::string> notices;
  j.notice = [&](const std::string& line) { notices.push_back(line); };
  estimate_depth(j, in.dir / "d.npy", record());
  ASSERT_EQ(notices.size(), 1u);
  EXPECT_NE(notices[0].find("GFLOP/s measured"), std::string::npos) << notices[0];
  EXPECT_NE(notices[0].find("DepthJob::input_size 14"), std::string::npos) << "half of 28: " << notices[0];
  // Not said when the estimate is expected to be short.
  notices.clear();
  j.forecast_after_s = 1e9;
  j.refresh_cache = true;
  estimate_depth(j, in.dir / "d.npy", record());
  EXPECT_TRUE(notices.empty());
}

// run's depth stage announces what it does: "estimating depth" when it estimates, "reading the cached estimate"
// when the cache holds it (not "estimating" for a read that takes a moment).
TEST_F(DepthEstimate, TheDepthStageSaysWhenItReadsTheCache) {
  RunOptions o = in.run_options(in.dir / "out", in.cache);
  o.render.depth_model = model;
  o.render.depth_input_size = 28;
  for (const char* expected : {"estimating depth with vda_random.safetensors", "reading the cached estimate of vda_random"}) {
    events.clear();
    StageTracker stages(record(), {});
    const nlohmann::json d = depth_stage(o, stages);
    ASSERT_FALSE(events.empty());
    EXPECT_EQ(events.front().stage, "depth");
    EXPECT_EQ(events.front().note.rfind(expected, 0), 0u) << events.front().note;
    EXPECT_EQ(d.at("from_cache").get<bool>(), std::string(expected).rfind("reading", 0) == 0);
  }
}

TEST(DurationText, ThreeSignificantDigitsAtMost) {
  EXPECT_EQ(duration_text(0.4123456), "0.41 s");
  EXPECT_EQ(duration_text(12.345678), "12.3 s");
  EXPECT_EQ(duration_text(245.2), "4 min 05 s");
  EXPECT_EQ(duration_text(4330), "1 h 12 min");
  EXPECT_EQ(count_text(1, "window", "windows"), "1 window");
  EXPECT_EQ(count_text(3, "window", "windows"), "3 windows");
}

}  // namespace
}  // namespace dvs
