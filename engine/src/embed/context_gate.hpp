// Who may use a dvs::Context now (dvs/context.hpp's threading rule, enforced). A context's device objects (its
// allocator, command pool, timeline, recordings) are not safe for two threads at once, so:
// - a direct call (a render, a run, a wait) holds the gate for its duration: a call from another thread waits for
//   it (calls are serialised); a call on the holding thread itself (from inside a progress callback) goes through;
// - a job (start_pipeline on a clip) holds it from its start until its work has ended, on its own thread: a call
//   from any other thread is then refused at once, as ErrorKind::invalid_argument naming the job and the remedy (a
//   second dvs::Context on the same device), since waiting would block a render loop for minutes;
// - a destructor (a scene's, a depth estimator's) cannot be refused: under a job it is deferred to the job's end
//   (run on the job's thread), otherwise it waits its turn like a call;
// - the context's own destructor cancels its job and waits for it to end.
#pragma once
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace dvs::embed {

class ContextGate {
 public:
  // What a job tells about itself for the refusal message ("the pipeline job on a clip of 9x64x64 frames, in stage
  // sample 3/50"), how to stop it and how to wait until its state says it has ended (the context's destructor).
  struct JobHooks {
    std::function<std::string()> describe;
    std::function<void()> cancel;
    std::function<void()> wait_for_end;
  };

  // A direct call: waits while another thread's call holds the gate; refused under a job (`call` names the call in
  // the message: "dvs::PointCloudScene::render").
  void enter(const char* call);
  void leave();

  // A job's start, on the caller's thread: refused when another job holds the gate; waits for a direct call of
  // another thread. From here until job_ended(), calls of other threads are refused.
  void claim_for_job(const char* call, JobHooks hooks);
  // The job's thread takes the gate over (its calls go through as the holder's) ...
  void job_started();
  // ... and gives it back when its work has ended (after running the destructors deferred to it).
  void job_ended();

  // Runs `destroy` now (waiting for another thread's direct call), or at the job's end when a job holds the gate
  // on another thread.
  void destroy_when_free(std::function<void()> destroy);

  // The context's destructor: asks a running job to stop and waits until it has ended (the gate given back and the
  // job's state no longer running).
  void cancel_and_wait_for_job();

 private:
  bool held_here() const { return depth_ > 0 && owner_ == std::this_thread::get_id(); }
  [[noreturn]] void refuse_for_job(const char* call) const;

  std::mutex mutex_;
  std::condition_variable freed_;
  std::thread::id owner_;  // the thread holding the gate (a direct call's, or the job's once started)
  int depth_ = 0;          // nested holds on the owner's thread
  bool job_ = false;       // a job has claimed the gate (from claim_for_job to job_ended)
  JobHooks job_hooks_;
  std::vector<std::function<void()>> deferred_;  // destructors waiting for the job's end
};

// A direct call's hold on the gate for one scope.
class GateUse {
 public:
  GateUse(ContextGate& gate, const char* call) : gate_(gate) { gate_.enter(call); }
  ~GateUse() { gate_.leave(); }
  GateUse(const GateUse&) = delete;
  GateUse& operator=(const GateUse&) = delete;

 private:
  ContextGate& gate_;
};

}  // namespace dvs::embed
