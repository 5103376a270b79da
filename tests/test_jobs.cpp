// dvs::Job (dvs/job.hpp): the blocking calls on a thread of their own. A render job writes what render_novel_view
// writes; cancelling or destroying a running job stops it and leaves no output; a failing job names the file and
// its getter rethrows dvs::Error; an exception from the progress callback fails the job cleanly; poll() never
// blocks.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>

#include "dvs/error.hpp"
#include "dvs/job.hpp"
#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/random_vda.hpp"

namespace dvs {
namespace {

using Clock = std::chrono::steady_clock;

class Jobs : public ::testing::Test {
 protected:
  test::PipelineInputs in;
  RenderJob render_job(const std::filesystem::path& out) const {
    RenderJob j;
    j.video = in.video;
    j.depth = in.depth;
    j.metric_depth = true;
    j.frames = 9;
    j.height = j.width = 64;
    j.out_dir = out;
    return j;
  }
  // A depth estimate of the clip with a tiny random model: some seconds on lavapipe, with progress at every step.
  DepthJob depth_job() const {
    DepthJob j;
    j.video = in.video;
    j.model = vda_model;
    j.input_size = 28;
    j.frames = 9;
    j.cache_dir = in.cache;
    return j;
  }
  std::filesystem::path vda_model = test::random_vda(in.dir / "vda");
};

TEST_F(Jobs, ARenderJobWritesWhatTheBlockingCallWrites) {
  const RenderSummary expected = render_novel_view(render_job(in.dir / "blocking"));
  std::vector<std::string> stages;
  Job job = start_render(render_job(in.dir / "job"), [&](const std::string& stage, int, int, const std::string&) {
    stages.push_back(stage);
  });
  job.wait();
  ASSERT_EQ(job.poll(), JobState::succeeded) << job.error();
  EXPECT_EQ(job.error(), "");
  const RenderSummary s = job.render_summary();
  EXPECT_EQ(s.frames, expected.frames);
  ASSERT_FALSE(stages.empty());
  EXPECT_EQ(stages.front(), "render");
  EXPECT_EQ(job.progress().stage, "render");
  auto sorted_files = [](const std::filesystem::path& dir) {
    auto names = test::files_in(dir);
    std::sort(names.begin(), names.end());
    return names;
  };
  EXPECT_EQ(sorted_files(in.dir / "job"), sorted_files(in.dir / "blocking"));
  for (const char* name : {"mask.npy", "poses.json", "render.mp4", "mask.mp4"})
    EXPECT_EQ(test::read_text(in.dir / "job" / name), test::read_text(in.dir / "blocking" / name)) << name;
  EXPECT_THROW(job.run_report(), Error) << "a render job has no run report";
}

TEST_F(Jobs, CancelDuringTheWorkStopsItAndLeavesNoOutput) {
  std::atomic<int> steps{0};
  Job job = start_depth(depth_job(), in.dir / "d.npy", [&](const std::string&, int, int, const std::string&) { ++steps; });
  while (steps == 0 && job.poll() == JobState::running) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  job.cancel();
  ASSERT_TRUE(job.wait_for(std::chrono::seconds(60))) << "a cancelled job kept running";
  EXPECT_EQ(job.poll(), JobState::cancelled);
  EXPECT_EQ(job.error(), "") << "a cancellation is not a failure";
  EXPECT_THROW(job.depth_summary(), Cancelled);
  EXPECT_FALSE(std::filesystem::exists(in.dir / "d.npy"));
}

// A whole run as a job: it finishes, reports every stage, and its output is the blocking call's, byte for byte (each
// with a cache of its own, so the job computes its inversion instead of reading the blocking run's).
TEST_F(Jobs, APipelineJobWritesWhatTheBlockingRunWrites) {
  run_pipeline(in.run_options(in.dir / "blocking", in.cache));
  std::vector<std::string> stages;
  Job job = start_pipeline(in.run_options(in.dir / "job", in.dir / "job_cache"),
                           [&](const std::string& stage, int, int, const std::string&) {
                             if (stages.empty() || stages.back() != stage) stages.push_back(stage);
                           });
  ASSERT_TRUE(job.wait_for(std::chrono::minutes(10))) << "the pipeline job did not finish";
  ASSERT_EQ(job.poll(), JobState::succeeded) << job.error();
  const RunReport report = job.run_report();
  EXPECT_FALSE(report.inversion_from_cache) << "the job's cache was empty";
  EXPECT_GE(stages.size(), 3u) << "a run reports its stages";
  EXPECT_EQ(report.output_mp4, in.dir / "job" / "output.mp4");
  for (const char* name : {"output.mp4", "render.mp4", "mask.mp4"}) {
    const std::string made = test::read_text(in.dir / "job" / name);
    EXPECT_GT(made.size(), 1000u) << name << " missing or empty";
    EXPECT_EQ(made, test::read_text(in.dir / "blocking" / name)) << name;
  }
  // The comparison can fail: another seed gives another output.
  RunOptions other = in.run_options(in.dir / "other", in.cache);
  other.seed += 1;
  run_pipeline(other);
  EXPECT_NE(test::read_text(in.dir / "other" / "output.mp4"), test::read_text(in.dir / "job" / "output.mp4"));
  EXPECT_THROW(job.render_summary(), Error) << "a pipeline job has no render summary";
}

TEST_F(Jobs, ACancelledPipelineJobLeavesNoRunOutput) {
  std::atomic<int> events{0};
  std::string first_stage;
  Job job = start_pipeline(in.run_options(in.dir / "out", in.cache), [&](const std::string& stage, int, int, const std::string&) {
    if (events++ == 0) first_stage = stage;
  });
  while (events == 0 && job.poll() == JobState::running) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  job.cancel();
  job.wait();
  EXPECT_EQ(job.poll(), JobState::cancelled) << job.error() << " (first stage " << first_stage << ")";
  EXPECT_THROW(job.run_report(), Cancelled);
  for (const char* name : {"output.mp4", "render.mp4", "mask.mp4", "run.json"})
    EXPECT_FALSE(std::filesystem::exists(in.dir / "out" / name)) << name << " left by a cancelled run";
}

TEST_F(Jobs, AFailingJobNamesTheFileAndItsGetterRethrows) {
  RunOptions o = in.run_options(in.dir / "out", in.cache);
  o.render.video = in.dir / "missing.mp4";
  Job job = start_pipeline(o);
  job.wait();
  EXPECT_EQ(job.poll(), JobState::failed);
  EXPECT_NE(job.error().find("missing.mp4"), std::string::npos) << job.error();
  try {
    job.run_report();
    ADD_FAILURE() << "run_report() of a failed job returned";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), job.error());
  }
  EXPECT_FALSE(std::filesystem::exists(in.dir / "out" / "output.mp4"));
}

TEST_F(Jobs, AProgressCallbackThatThrowsFailsTheJobCleanly) {
  Job job = start_depth(depth_job(), in.dir / "d.npy", [](const std::string&, int step, int, const std::string&) {
    if (step == 1) throw std::runtime_error("the app's callback broke");
  });
  job.wait();
  EXPECT_EQ(job.poll(), JobState::failed);
  EXPECT_NE(job.error().find("progress callback threw: the app's callback broke"), std::string::npos) << job.error();
  EXPECT_THROW(job.depth_summary(), Error);
  EXPECT_FALSE(std::filesystem::exists(in.dir / "d.npy"));
}

TEST_F(Jobs, PollNeverBlocks) {
  std::atomic<bool> in_callback{false};
  // The job's thread sits in its progress callback for a while: poll() and progress() must not wait for it.
  Job job = start_depth(depth_job(), in.dir / "d.npy", [&](const std::string&, int step, int, const std::string&) {
    if (step != 1) return;
    in_callback = true;
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
  });
  while (!in_callback && job.poll() == JobState::running) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  // Were poll() or progress() to wait for the job's thread, they would take the callback's 300 ms. The median is
  // what a render loop pays per frame; the slowest allows for this thread being descheduled on a loaded machine.
  std::vector<double> ms;
  for (const auto until = Clock::now() + std::chrono::milliseconds(200); Clock::now() < until;) {
    const auto t = Clock::now();
    const JobState s = job.poll();
    job.progress();
    ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t).count());
    EXPECT_EQ(s, JobState::running);
  }
  std::sort(ms.begin(), ms.end());
  ASSERT_FALSE(ms.empty());
  EXPECT_LT(ms[ms.size() / 2], 1.0) << "median of " << ms.size() << " polls";
  EXPECT_LT(ms.back(), 100.0) << "the slowest of " << ms.size() << " polls";
  job.wait();
  EXPECT_EQ(job.poll(), JobState::succeeded) << job.error();
  EXPECT_EQ(job.depth_summary().frames, 9);
  EXPECT_TRUE(std::filesystem::is_regular_file(in.dir / "d.npy"));
}

TEST_F(Jobs, DestroyingARunningJobCancelsIt) {
  std::atomic<int> steps{0}, total{0};
  int steps_before = 0;
  {
    Job job = start_depth(depth_job(), in.dir / "d.npy", [&](const std::string&, int step, int all, const std::string&) {
      ++steps;
      total = all;
    });
    while (steps == 0 && job.poll() == JobState::running) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    ASSERT_EQ(job.poll(), JobState::running) << "the job ended before the test could destroy it";
    steps_before = steps;
  }  // ~Job: cancels and joins
  // The job checks for cancellation before every progress event: at most the step under way when the handle went.
  EXPECT_LE(steps - steps_before, 2) << "the job ran on after its handle was destroyed";
  EXPECT_LT(steps, total) << "the estimate ran to its end";
  EXPECT_FALSE(std::filesystem::exists(in.dir / "d.npy"));
}

}  // namespace
}  // namespace dvs
