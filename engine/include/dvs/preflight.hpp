// Preflight: everything about a job that is knowable before its first stage, checked in milliseconds from the
// options, the model's config.json files, tokenizer and scheduler files, the safetensors headers (presence,
// shapes, dtypes), the LoRA file, the VAE tiling and the device's memory as the planner (dvs/plan.hpp) sees it.
// Every problem is collected, each with what to do, so a user fixes them all at once. No device work, no file
// written. What `dvs run --check` and `dvs render --check` print, and what every run does first.
#pragma once
#include <string>
#include <vector>

#include "dvs/pipeline.hpp"
#include "dvs/render.hpp"
#include "dvs/api.hpp"

namespace dvs {

enum class JobKind { run, invert };

struct DVS_API PreflightReport {
  std::vector<std::string> problems;  // each: what is wrong and the fix
  std::vector<std::string> notes;     // facts worth a line (sizes, the plan's peak), not problems
  bool ok() const { return problems.empty(); }
  // "preflight found 2 problems; nothing was run:\n  - …\n  - …"
  std::string message() const;
};

DVS_API PreflightReport preflight(const RunOptions& o, JobKind kind);

// The geometry stage's inputs alone (video, depth or depth model, camera path, size, output folder), as
// render_novel_view needs them.
DVS_API PreflightReport preflight_render(const RenderJob& job);

}  // namespace dvs
