// dvs/job.hpp: run_pipeline (on files or on a clip in memory), render_novel_view and estimate_depth on a thread of
// their own. The thread owns nothing but the shared State; the Job handle cancels and joins it when destroyed, so a
// job never outlives its handle. Whatever the work throws is kept (as a dvs::Error: embed/public_call.hpp) and
// rethrown by the result getters on the caller's thread. A job on a clip holds its context (embed/context_gate.hpp)
// from its start until its work has ended.
#include "dvs/job.hpp"

#include <atomic>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <optional>
#include <thread>

#include "dvs/clip_run.hpp"
#include "dvs/error.hpp"
#include "embed/clip_run_on_device.hpp"
#include "embed/context_core.hpp"
#include "embed/public_call.hpp"

namespace dvs {

struct Job::State {
  std::atomic<JobState> state{JobState::running};
  std::atomic<bool> cancel_asked{false};
  std::string kind;  // "pipeline", "render" or "depth": which result getter applies
  mutable std::mutex mutex;
  std::condition_variable finished;
  JobProgress progress;  // guarded by mutex
  std::string error;     // guarded by mutex; set before `state` leaves running
  std::exception_ptr exception;
  std::optional<RunReport> run_report;
  std::optional<RenderSummary> render_summary;
  std::optional<DepthSummary> depth_summary;
  std::thread thread;

  // The caller's progress callback behind the job's own record of the last event. An exception from the callback
  // fails the job as a dvs::Error (the blocking call then cleans up as for any failure), not the process.
  ProgressFn progress_fn(ProgressFn user) {
    return [this, user = std::move(user)](const std::string& stage, int step, int total, const std::string& note) {
      {
        std::lock_guard<std::mutex> lock(mutex);
        progress = {stage, note, step, total};
      }
      if (!user) return;
      try {
        user(stage, step, total, note);
      } catch (const Cancelled&) {
        throw;
      } catch (const std::exception& e) {
        throw Error("the job's progress callback threw: " + std::string(e.what()));
      } catch (...) {
        throw Error("the job's progress callback threw an exception that is not a std::exception");
      }
    };
  }
  CancelFn cancel_fn() {
    return [this] { return cancel_asked.load(); };
  }

  template <class Work>
  void run(Work work) {
    JobState end = JobState::succeeded;
    std::string message;
    std::exception_ptr caught;
    try {
      embed::public_call("dvs::Job", work);
    } catch (const Cancelled& e) {
      end = JobState::cancelled, message = e.what(), caught = std::current_exception();
    } catch (const std::exception& e) {
      end = JobState::failed, message = e.what(), caught = std::current_exception();
    } catch (...) {
      end = JobState::failed, message = "the job failed with an exception that is not a std::exception";
      caught = std::current_exception();
    }
    {
      std::lock_guard<std::mutex> lock(mutex);
      exception = caught;
      if (end == JobState::failed) error = message;
      state = end;
    }
    finished.notify_all();
  }

  // Waits for the end of the work, then rethrows what it threw, or refuses a getter of another kind of job.
  void check_result(const char* getter, const char* want) {
    {
      std::unique_lock<std::mutex> lock(mutex);
      finished.wait(lock, [this] { return state != JobState::running; });
    }
    if (exception) std::rethrow_exception(exception);
    if (kind != want)
      throw Error(std::string("dvs::Job::") + getter + ": this is a " + kind + " job; its result is " +
                  (kind == "pipeline" ? "run_report()" : kind == "render" ? "render_summary()" : "depth_summary()"),
                  ErrorKind::invalid_argument);
  }

  void stop() {
    cancel_asked = true;
    if (thread.joinable()) thread.join();
  }
};

Job::Job(std::shared_ptr<State> state) : state_(std::move(state)) {}
Job::Job(Job&&) noexcept = default;
Job& Job::operator=(Job&& other) noexcept {
  if (this != &other) {
    if (state_) state_->stop();
    state_ = std::move(other.state_);
  }
  return *this;
}
Job::~Job() {
  if (state_) state_->stop();
}

namespace {
void check_handle(const std::shared_ptr<Job::State>& s, const char* call) {
  if (!s)
    throw Error(std::string("dvs::Job::") + call + ": this Job was moved from; use the Job it was moved to",
                ErrorKind::invalid_argument);
}
}  // namespace

JobState Job::poll() const {
  check_handle(state_, "poll");
  return state_->state.load();
}

JobProgress Job::progress() const {
  check_handle(state_, "progress");
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->progress;
}

bool Job::wait_for(std::chrono::milliseconds limit) {
  check_handle(state_, "wait_for");
  std::unique_lock<std::mutex> lock(state_->mutex);
  return state_->finished.wait_for(lock, limit, [this] { return state_->state != JobState::running; });
}

void Job::wait() {
  check_handle(state_, "wait");
  std::unique_lock<std::mutex> lock(state_->mutex);
  state_->finished.wait(lock, [this] { return state_->state != JobState::running; });
}

void Job::cancel() {
  check_handle(state_, "cancel");
  state_->cancel_asked = true;
}

std::string Job::error() const {
  check_handle(state_, "error");
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->error;
}

RunReport Job::run_report() {
  check_handle(state_, "run_report");
  state_->check_result("run_report", "pipeline");
  return *state_->run_report;
}

RenderSummary Job::render_summary() {
  check_handle(state_, "render_summary");
  state_->check_result("render_summary", "render");
  return *state_->render_summary;
}

DepthSummary Job::depth_summary() {
  check_handle(state_, "depth_summary");
  state_->check_result("depth_summary", "depth");
  return *state_->depth_summary;
}

// The work's inputs are copied into the thread's closure: the caller's objects may go away at once.
Job start_pipeline(const RunOptions& options, const ProgressFn& progress) {
  auto s = std::make_shared<Job::State>();
  s->kind = "pipeline";
  s->thread = std::thread([st = s.get(), options, fn = s->progress_fn(progress)] {
    st->run([&] { st->run_report = run_pipeline(options, fn, st->cancel_fn()); });
  });
  return Job(s);
}

namespace {

// "the pipeline job on the clip u8[9x64x64x3], in stage sample (3 of 50)": what a refused call names.
std::string describe_clip_job(const Job::State& st, const std::string& frames) {
  const JobProgress p = [&] {
    std::lock_guard<std::mutex> lock(st.mutex);
    return st.progress;
  }();
  std::string text = "the pipeline job on the clip " + frames;
  if (p.stage.empty()) return text + ", starting";
  text += ", in stage " + p.stage;
  if (p.total > 0) text += " (" + std::to_string(p.step) + " of " + std::to_string(p.total) + ")";
  return text;
}

// The clip's memory (or buffers) and the views are the caller's (dvs/clip_run.hpp: valid until the job has finished);
// the options, the view descriptions and the poses are copied. The context's core is held by the thread, so the job
// never touches the dvs::Context object (which may be destroyed: its destructor cancels the job and waits).
template <class Clip, class Results>
std::shared_ptr<Job::State> start_clip_job(Context& ctx, const RunOptions& options, const Clip& clip, const Results& out,
                                           const ProgressFn& progress) {
  auto s = std::make_shared<Job::State>();
  s->kind = "pipeline";
  std::shared_ptr<embed::ContextCore> core = ctx.core();
  Job::State* st = s.get();
  // The gate calls these until the job gives it back; wait_for_end may run after that, when the Job may be gone.
  const std::weak_ptr<Job::State> weak_state = s;
  embed::ContextGate::JobHooks hooks;
  hooks.describe = [st, frames = clip.frames.describe()] { return describe_clip_job(*st, frames); };
  hooks.cancel = [st] { st->cancel_asked = true; };
  hooks.wait_for_end = [weak_state] {
    if (const auto held = weak_state.lock()) {
      std::unique_lock<std::mutex> lock(held->mutex);
      held->finished.wait(lock, [&] { return held->state != JobState::running; });
    }
  };
  core->gate.claim_for_job("dvs::start_pipeline", std::move(hooks));
  try {
    s->thread = std::thread([st, core, options, clip, out, fn = s->progress_fn(progress)] {
      core->gate.job_started();
      st->run([&] {
        // The context is given back when the work ends, before the job's state says so.
        struct Release {
          embed::ContextGate& gate;
          ~Release() { gate.job_ended(); }
        } release{core->gate};
        st->run_report = embed::run_clip(*core->device, options, clip, out, fn, st->cancel_fn());
      });
    });
  } catch (...) {  // no thread: the claim is given back at once
    core->gate.job_ended();
    throw;
  }
  return s;
}

}  // namespace

Job start_pipeline(Context& ctx, const RunOptions& options, const ClipView& clip, const ClipResultViews& out,
                   const ProgressFn& progress) {
  return Job(start_clip_job(ctx, options, clip, out, progress));
}

Job start_pipeline(Context& ctx, const RunOptions& options, const ClipDeviceView& clip, const ClipResultDeviceViews& out,
                   const ProgressFn& progress) {
  return Job(start_clip_job(ctx, options, clip, out, progress));
}

Job start_render(const RenderJob& job, const ProgressFn& progress) {
  auto s = std::make_shared<Job::State>();
  s->kind = "render";
  s->thread = std::thread([st = s.get(), job, fn = s->progress_fn(progress)] {
    st->run([&] {
      st->render_summary = render_novel_view(job, [&](const std::string& line) { fn("render", 0, 0, line); },
                                             st->cancel_fn());
    });
  });
  return Job(s);
}

Job start_depth(const DepthJob& job, const std::filesystem::path& out, const ProgressFn& progress) {
  auto s = std::make_shared<Job::State>();
  s->kind = "depth";
  s->thread = std::thread([st = s.get(), job, out, fn = s->progress_fn(progress)] {
    st->run([&] { st->depth_summary = estimate_depth(job, out, fn, st->cancel_fn()); });
  });
  return Job(s);
}

}  // namespace dvs
