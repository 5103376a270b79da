// Runs a job's stages: times each one, forwards progress, polls for cancellation at every stage boundary and
// diffusion step, and names the stage in any error it lets through (an out-of-memory error then says where
// memory ran out).
#pragma once
#include <chrono>
#include <string>
#include <utility>
#include <vector>

#include "diffusion/sampler.hpp"
#include "dvs/error.hpp"
#include "dvs/pipeline.hpp"
#include "tensor/ops_check.hpp"
#include "vk/context.hpp"

namespace dvs {

// What a NaN/Inf in a stage's result usually means, appended to the error.
extern const char* const kNonFiniteHint;

class StageTracker {
 public:
  StageTracker(const ProgressFn& progress, const CancelFn& cancelled);

  // Starts `stage` (after checking for cancellation) and announces it with `note`.
  void begin(const std::string& stage, const std::string& note);
  void end();  // records the time since begin()
  void say(int step, int total, const std::string& note) const;
  void check_cancelled() const;  // throws dvs::Cancelled when cancellation was asked for
  // Progress and cancellation for a diffusion loop run in the current stage. With `check`, the scans each step
  // recorded into it (see TransformerDenoiser::watch) are read after the step and a NaN/Inf stops the job.
  diffusion::LoopCallbacks loop_callbacks(ops::NonFiniteCheck* check = nullptr) const;
  // For vk::ScopedSegmentHook: between the bounded submissions of one recording (a transformer block, a T5
  // layer, a VAE step) it polls for cancellation and, at most every kSegmentProgressS, repeats the last
  // progress line with where the work is ("step 3: transformer block 17/42").
  vk::SegmentHook segment_hook() const;
  static constexpr double kSegmentProgressS = 0.5;
  const std::vector<StageTime>& times() const { return times_; }

  // Runs the whole job: diffusion::Cancelled becomes dvs::Cancelled, any other dvs::Error thrown inside a
  // stage is rethrown as "<stage> stage: <message>".
  template <class Job>
  auto run(Job&& job) -> decltype(job()) {
    try {
      return job();
    } catch (const Cancelled&) {
      throw;
    } catch (const diffusion::Cancelled&) {
      throw Cancelled();
    } catch (const Error& e) {
      if (stage_.empty()) throw;
      throw Error(stage_ + " stage: " + e.what());
    }
  }

 private:
  bool cancel_requested() const;

  ProgressFn progress_;
  CancelFn cancelled_;
  std::string stage_;
  // The last say(), which segment progress repeats with its own note.
  mutable int last_step_ = 0, last_total_ = 0;
  mutable std::string last_note_;
  std::chrono::steady_clock::time_point start_;
  std::vector<StageTime> times_;
};

}  // namespace dvs
