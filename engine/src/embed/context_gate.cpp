#include "embed/context_gate.hpp"

#include "dvs/error.hpp"

namespace dvs::embed {
namespace {
// A destructor's body: never lets an exception out of the gate (which would leave it held).
void run_destructor(const std::function<void()>& destroy) noexcept {
  try {
    destroy();
  } catch (...) {
  }
}
}  // namespace

void ContextGate::refuse_for_job(const char* call) const {
  const std::string job = job_hooks_.describe ? job_hooks_.describe() : "a job";
  throw Error(std::string(call) + ": this dvs::Context is in use by " + job +
                  " (dvs::start_pipeline / dvs_job_start_pipeline_clip) until that job ends; calls on one context wait "
                  "for each other but not for a job, which may run for minutes. Make a second dvs::Context on the same "
                  "device for this work (dvs::Context again, or dvs::Context(HostDevice) with the same objects; C: "
                  "dvs_context_create / dvs_context_create_on_host), as docs/embedding.md's \"A preview beside a "
                  "job\" shows, or wait for the job first (Job::wait, dvs_job_wait)",
              ErrorKind::invalid_argument);
}

void ContextGate::enter(const char* call) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (held_here()) {
    ++depth_;
    return;
  }
  if (job_) refuse_for_job(call);
  freed_.wait(lock, [this] { return depth_ == 0 || job_; });
  if (job_) refuse_for_job(call);  // a job claimed the context while this call waited
  owner_ = std::this_thread::get_id();
  depth_ = 1;
}

void ContextGate::leave() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (--depth_ == 0) {
    owner_ = {};
    freed_.notify_all();
  }
}

void ContextGate::claim_for_job(const char* call, JobHooks hooks) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (job_) refuse_for_job(call);
  if (held_here())
    throw Error(std::string(call) + ": a job cannot start on this dvs::Context from inside another call on it (a "
                                    "progress callback): start it after that call has returned, or on a second "
                                    "dvs::Context",
                ErrorKind::invalid_argument);
  freed_.wait(lock, [this] { return depth_ == 0 || job_; });
  if (job_) refuse_for_job(call);
  job_ = true;
  job_hooks_ = std::move(hooks);
}

void ContextGate::job_started() {
  std::lock_guard<std::mutex> lock(mutex_);
  owner_ = std::this_thread::get_id();
  depth_ = 1;
}

void ContextGate::job_ended() {
  std::unique_lock<std::mutex> lock(mutex_);
  // The destructors deferred to the job's end run on its thread while it still holds the gate (more may come while
  // they run).
  while (!deferred_.empty()) {
    std::vector<std::function<void()>> due = std::move(deferred_);
    deferred_.clear();
    owner_ = std::this_thread::get_id();
    depth_ = 1;
    lock.unlock();
    for (auto& destroy : due) run_destructor(destroy);
    lock.lock();
  }
  owner_ = {};
  depth_ = 0;
  job_ = false;
  job_hooks_ = {};
  freed_.notify_all();
}

void ContextGate::destroy_when_free(std::function<void()> destroy) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (held_here()) {  // inside a call on this context (or on the job's thread): the holder may destroy
    lock.unlock();
    run_destructor(destroy);
    return;
  }
  if (job_) {
    deferred_.push_back(std::move(destroy));
    return;
  }
  freed_.wait(lock, [this] { return depth_ == 0 || job_; });
  if (job_) {
    deferred_.push_back(std::move(destroy));
    return;
  }
  owner_ = std::this_thread::get_id();
  depth_ = 1;
  lock.unlock();
  run_destructor(destroy);
  lock.lock();
  depth_ = 0;
  owner_ = {};
  freed_.notify_all();
}

void ContextGate::cancel_and_wait_for_job() {
  std::unique_lock<std::mutex> lock(mutex_);
  if (!job_) return;
  if (job_hooks_.cancel) job_hooks_.cancel();
  if (held_here()) return;  // destroyed from the job's own thread (its progress callback): it stops at its next check
  const JobHooks hooks = job_hooks_;
  freed_.wait(lock, [this] { return !job_; });
  lock.unlock();
  // The job gives the gate back just before its state changes (so that after Job::wait the context is free): wait
  // for that too.
  if (hooks.wait_for_end) hooks.wait_for_end();
}

}  // namespace dvs::embed
