// Long work without blocking the caller: a job runs on a thread of its own and the application polls or waits on
// its handle (a render loop checks poll() once per frame: poll() never blocks). A job on a clip holds its Context
// until it ends, so the render loop draws on a second Context of the same device (dvs/context.hpp; docs/embedding.md,
// "A preview beside a job"). Progress and cancellation as the blocking calls. Only dvs::Error comes out of a job.
#pragma once
#include <chrono>
#include <memory>
#include <string>

#include "dvs/api.hpp"
#include "dvs/depth_estimate.hpp"
#include "dvs/pipeline.hpp"
#include "dvs/render.hpp"

namespace dvs {

class Context;
struct ClipView;
struct ClipResultViews;
struct ClipDeviceView;
struct ClipResultDeviceViews;

enum class JobState { running, succeeded, failed, cancelled };

struct JobProgress {
  std::string stage, note;  // the last progress event
  int step = 0, total = 0;
};

class DVS_API Job {
 public:
  Job(Job&&) noexcept;
  Job& operator=(Job&&) noexcept;
  ~Job();  // cancels and waits when still running

  JobState poll() const;                          // never blocks
  JobProgress progress() const;                   // never blocks
  bool wait_for(std::chrono::milliseconds limit);  // true when finished within `limit`
  void wait();
  void cancel();                                  // asks the job to stop at its next check; poll() says when it has
  std::string error() const;                      // the dvs::Error message of a failed job ("" otherwise)
  // The results: wait(), then the report of a succeeded job; rethrows the job's dvs::Error / dvs::Cancelled.
  RunReport run_report();
  RenderSummary render_summary();
  DepthSummary depth_summary();

  struct State;

 private:
  explicit Job(std::shared_ptr<State> state);
  std::shared_ptr<State> state_;
  friend DVS_API Job start_pipeline(const RunOptions&, const ProgressFn&);
  friend DVS_API Job start_pipeline(Context&, const RunOptions&, const ClipView&, const ClipResultViews&,
                                    const ProgressFn&);  // dvs/clip_run.hpp
  friend DVS_API Job start_pipeline(Context&, const RunOptions&, const ClipDeviceView&, const ClipResultDeviceViews&,
                                    const ProgressFn&);  // dvs/clip_run.hpp
  friend DVS_API Job start_render(const RenderJob&, const ProgressFn&);
  friend DVS_API Job start_depth(const DepthJob&, const std::filesystem::path&, const ProgressFn&);
};

// run_pipeline, render_novel_view and estimate_depth on a thread of their own. `progress` is called on the job's
// thread (keep it short; the last event is also in Job::progress()).
DVS_API Job start_pipeline(const RunOptions& options, const ProgressFn& progress = {});
DVS_API Job start_render(const RenderJob& job, const ProgressFn& progress = {});
DVS_API Job start_depth(const DepthJob& job, const std::filesystem::path& out, const ProgressFn& progress = {});

}  // namespace dvs
