// A whole run on a clip in memory (dvs/clip_run.hpp) on a context's device objects, checks included: what the public
// run_pipeline calls run at the context's turn, and what a job (embed/job.cpp) runs on its own thread while it holds
// the context.
#pragma once
#include "dvs/clip_run.hpp"
#include "vk/context.hpp"

namespace dvs::embed {

RunReport run_clip(vk::Context& device, const RunOptions& options, const ClipView& clip, const ClipResultViews& out,
                   const ProgressFn& progress, const CancelFn& cancelled);
RunReport run_clip(vk::Context& device, const RunOptions& options, const ClipDeviceView& clip,
                   const ClipResultDeviceViews& out, const ProgressFn& progress, const CancelFn& cancelled);

}  // namespace dvs::embed
