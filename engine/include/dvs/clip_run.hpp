// A whole run on a clip in memory, on a context the application made (dvs's own device or the application's, see
// dvs/context.hpp): frames, depth and camera path go in as host views, the new view, the render, its mask and the
// sampled latent come back in the application's memory. No video or depth file is read and nothing is written but
// the inversion and latent caches (RunOptions::use_cache / cache_dir, as for `dvs run`).
//
// The same stages and the same numbers as run_pipeline on files (docs/design.md §1): given the frames a video decode
// gives and the depth a depth file holds, the sampled latent is the one `dvs run` samples.
#pragma once
#include <vector>

#include "dvs/api.hpp"
#include "dvs/context.hpp"
#include "dvs/job.hpp"
#include "dvs/pipeline.hpp"
#include "dvs/scene.hpp"
#include "dvs/views.hpp"

namespace dvs {

struct ClipView {
  // u8 [F,H,W,3] RGB (what a video decoder gives) or f32 [F,3,H,W] RGB in [−1,1], already at the working size:
  // H and W multiples of 8, F = 4k+1 frames (what the model takes).
  ConstHostView frames;
  // f32 [F,H,W] at the frames' size: disparity (what DepthEstimator and `dvs depth` give), or metric depth with
  // RunOptions::render.metric_depth.
  ConstHostView depth;
  // One world-to-camera transform per frame (dvs/scene.hpp's convention: frame 0's camera is the world). Empty: the
  // path RunOptions::render.trajectory names (a preset such as "pan_left:30", or a .txt/.json/.gltf/.glb file).
  std::vector<Pose> poses;
};

// Where the results go; each view's shape and type are checked before any work starts. Only `output` is required;
// leave the data of another view null when it is not wanted.
struct ClipResultViews {
  HostView output;  // the new view: u8 [F,H,W,3] RGB or f32 [F,3,H,W] in [−1,1]
  HostView render;  // the splat render the model started from: the same forms (holes black / −1)
  HostView mask;    // f32 [F,H,W], 1 = visible in the render
  HostView latent;  // f32 [Fl,C,h,w]: the sampled latent the VAE decodes (Fl = (F−1)/4+1, C and h×w the VAE's)
};

// RunOptions as for run_pipeline, except that render.video, render.depth, render.depth_model and render.out_dir must
// be empty (the clip replaces them), render.height/width must be the frames' size and render.frames 0 or F; each
// mismatch is a dvs::Error naming the option. render.device is ignored (the context is the device). Errors and
// cancellation as run_pipeline; a failed or cancelled run leaves the result views' contents undefined.
DVS_API RunReport run_pipeline(Context& ctx, const RunOptions& options, const ClipView& clip,
                               const ClipResultViews& out, const ProgressFn& progress = {},
                               const CancelFn& cancelled = {});

// The same on a thread of its own. The clip's memory and the result views must stay valid until the job has finished
// (Job::poll says when). The job holds the context until then: a call on it from another thread is refused
// (dvs::Error naming the job; work beside the job goes on a second Context of the same device), a second job on it
// too, and destroying the Context cancels the job and waits for its end. Errors of the options and views make the job
// fail (ErrorKind::invalid_argument).
DVS_API Job start_pipeline(Context& ctx, const RunOptions& options, const ClipView& clip, const ClipResultViews& out,
                           const ProgressFn& progress = {});

// The same clip in the application's device buffers (dvs/views.hpp: VkBuffers of the context's device, so a
// HostDevice context; inputs with TRANSFER_SRC usage, results with TRANSFER_DST), in the forms of ClipView and
// ClipResultViews; a result whose buffer is VK_NULL_HANDLE is not wanted (output is required). The application's
// writes of the inputs must be finished or ordered before the call (on the same queue, or by
// Context::wait_before_next). The inputs are copied in at the start (the render stage runs on host memory), the
// sampled latent is copied device to device, and the call returns once every copy into the application's buffers
// has finished: its buffers can be used at once. Shapes, types and buffer ranges are checked before any work.
struct ClipDeviceView {
  DeviceBufferView frames;  // u8 [F,H,W,3] or f32 [F,3,H,W]
  DeviceBufferView depth;   // f32 [F,H,W]
  std::vector<Pose> poses;  // as ClipView::poses
};

struct ClipResultDeviceViews {
  DeviceBufferView output, render;  // u8 [F,H,W,3] or f32 [F,3,H,W]
  DeviceBufferView mask;            // f32 [F,H,W]
  DeviceBufferView latent;          // f32 [Fl,C,h,w]
};

DVS_API RunReport run_pipeline(Context& ctx, const RunOptions& options, const ClipDeviceView& clip,
                               const ClipResultDeviceViews& out, const ProgressFn& progress = {},
                               const CancelFn& cancelled = {});
DVS_API Job start_pipeline(Context& ctx, const RunOptions& options, const ClipDeviceView& clip,
                           const ClipResultDeviceViews& out, const ProgressFn& progress = {});

}  // namespace dvs
