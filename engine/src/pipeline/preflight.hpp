// Preflight: everything about a job that is knowable before stage 1, checked in milliseconds from the options,
// the model's config.json files, tokenizer and scheduler files, the safetensors headers (presence, shapes,
// dtypes), the LoRA file, the VAE tiling and the device's memory as the planner (memory_plan.hpp) sees it.
// Every problem is collected, each with what to do, so a user fixes them all at once instead of learning
// of them one by one after minutes of rendering, encoding and text encoding. No device work, no file written.
#pragma once
#include <string>
#include <vector>

#include "dvs/pipeline.hpp"

namespace dvs {

enum class JobKind { run, invert };

struct PreflightReport {
  std::vector<std::string> problems;  // each: what is wrong and the fix
  std::vector<std::string> notes;     // facts worth a line (sizes, the plan's peak), not problems
  bool ok() const { return problems.empty(); }
  // "preflight found 2 problems; nothing was run:\n  - …\n  - …"
  std::string message() const;
};

PreflightReport preflight(const RunOptions& o, JobKind kind);

// Throws dvs::Error with report.message() when there is any problem.
void require_preflight(const RunOptions& o, JobKind kind);

}  // namespace dvs
