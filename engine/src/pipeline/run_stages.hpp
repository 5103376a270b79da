// The whole run's stages (render, encode, text, inversion, SLM/K-RNR, sampling, decode), written once for both
// ends a run can have: `dvs run` on files (run_pipeline.cpp: a video and a depth file in, videos and run.json out,
// dvs's own device) and a run on a clip in memory (embed/clip_run.cpp: views in and out, the application's
// context). What differs between the two is a RunEnds; the stages and their numbers are the same.
#pragma once
#include <string>
#include <vector>

#include "dvs/pipeline.hpp"
#include "io/host_tensor.hpp"
#include "pipeline/render_stage.hpp"
#include "pipeline/run_record.hpp"
#include "pipeline/stage_tracker.hpp"
#include "tensor/tensor.hpp"
#include "vk/context.hpp"

namespace dvs {

// What a run hands its destination after the decode.
struct RunResults {
  const RenderedInput& in;   // the clip, its render and mask
  const HostTensor& output;  // [F,3,H,W] in [−1,1], the new view
  const Tensor& latent;      // the sampled latent (diffusion layout [Fl,C,h,w]) the VAE decoded
};

class RunEnds {
 public:
  virtual ~RunEnds() = default;
  // Every problem knowable before device work (the preflight), and whatever must be held to the end of the run.
  virtual void check(const RunOptions& o) = 0;
  // What names the clip in the inversion and latent caches' keys (files: their fingerprints and the trajectory).
  virtual std::vector<std::string> input_key(const RunOptions& o) const = 0;
  // Stages 1–2: the clip at the working size, its depth, camera path, render and mask.
  virtual RenderedInput input(vk::Context& ctx, const RunOptions& o, StageTracker& stages) = 0;
  // The "write" stage: the results where they go; sets the report's paths.
  virtual void write(vk::Context& ctx, const RunResults& results, RunReport& report, StageTracker& stages) = 0;
  // After the report is complete: the run's record (files: run.json, then the output folder is committed).
  virtual void finish(const RunOptions& o, const RunReport& report, const RunRecordExtras& extras,
                      StageTracker& stages) = 0;
};

// The stages on `device` (null: dvs's own, made from options.render.device for this run).
RunReport run_stages(const RunOptions& options, RunEnds& ends, vk::Context* device, StageTracker& stages);

}  // namespace dvs
