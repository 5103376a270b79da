// The preflight (dvs/preflight.hpp: the checks and their report, public) as the pipeline's stages call it.
#pragma once
#include "dvs/preflight.hpp"

namespace dvs {

namespace vk {
struct DeviceCaps;
}

// What a preflight looks at besides the model and the options. A run on a clip in memory (dvs/clip_run.hpp) has no
// video, depth or output folder to check, may bring its camera path as poses, and runs on the context's device.
struct PreflightScope {
  bool input_files = true;           // the video, depth (or depth model) and output folder
  bool trajectory = true;            // render.trajectory (false: the poses replace it)
  const vk::DeviceCaps* device = nullptr;  // null: the device render.device names
};

PreflightReport preflight(const RunOptions& o, JobKind kind, const PreflightScope& scope);

// Throws dvs::Error with report.message() when there is any problem.
void require_preflight(const RunOptions& o, JobKind kind, const PreflightScope& scope = {});

}  // namespace dvs
