// Runs a job's stages: times each one, forwards progress, polls for cancellation at every stage boundary and
// diffusion step, and names the stage in any error it lets through (an out-of-memory error then says where
// memory ran out).
#pragma once
#include <chrono>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "diffusion/sampler.hpp"
#include "dvs/error.hpp"
#include "dvs/pipeline.hpp"
#include "tensor/ops_check.hpp"
#include "vk/check.hpp"
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

  // What an out-of-device-memory error in `stage` should add (pipeline/memory_advice.hpp); unset: the
  // allocator's generic advice.
  void set_memory_advice(std::function<std::string(const std::string& stage)> advice) {
    memory_advice_ = std::move(advice);
  }

  // Runs the whole job: diffusion::Cancelled becomes dvs::Cancelled, any other dvs::Error thrown inside a
  // stage is rethrown as "<stage> stage: <message>". Device faults say exactly where they happened, also
  // between stages (loading a model) and before the first ("after the render stage: ", "start-up: "), and out
  // of device memory adds the stage's memory advice.
  template <class Job>
  auto run(Job&& job) -> decltype(job()) {
    try {
      return job();
    } catch (const Cancelled&) {
      throw;
    } catch (const diffusion::Cancelled&) {
      throw Cancelled();
    } catch (const vk::DeviceOutOfMemory& e) {
      const std::string advice_stage = ended_ ? "" : stage_;  // between stages: a model's weights, the run's advice
      throw Error(where() + ": " + e.detail() +
                      (memory_advice_ ? memory_advice_(advice_stage) : std::string(vk::kOutOfMemoryHint)),
                  ErrorKind::out_of_memory);
    } catch (const vk::DeviceLost& e) {
      throw Error(where() + ": " + e.what(), ErrorKind::device_lost);
    } catch (const Error& e) {
      if (stage_.empty()) throw;
      throw Error(stage_ + " stage: " + e.what(), e.kind());
    }
  }

 private:
  bool cancel_requested() const;
  // "<stage> stage", "after the <stage> stage" (between two stages) or "start-up" (before the first).
  std::string where() const;

  ProgressFn progress_;
  CancelFn cancelled_;
  std::string stage_;
  bool ended_ = false;  // stage_ has ended and the next has not begun
  std::function<std::string(const std::string&)> memory_advice_;
  // The last say(), which segment progress repeats with its own note.
  mutable int last_step_ = 0, last_total_ = 0;
  mutable std::string last_note_;
  std::chrono::steady_clock::time_point start_;
  std::vector<StageTime> times_;
};

}  // namespace dvs
