// Stage 1–2 of the pipeline, shared by `dvs render` and `dvs run`: decode the video at the working size,
// load and fit the depth, build the camera path and splat every frame into its new view.
#pragma once
#include <functional>
#include <optional>
#include <string>

#include "dvs/render.hpp"
#include "geometry/camera.hpp"
#include "geometry/trajectory.hpp"
#include "io/host_tensor.hpp"
#include "vk/context.hpp"
#include "vk/device_info.hpp"

namespace dvs {

struct RenderedInput {
  HostTensor rgb;     // [F,3,H,W] in [−1,1], the input at the working size
  HostTensor depth;   // [F,H,W] metric depth (after the disparity conversion)
  HostTensor render;  // [F,3,H,W] in [−1,1], holes −1
  HostTensor mask;    // [F,H,W], 1 = visible
  geometry::Trajectory trajectory;
  geometry::Intrinsics K;
  double fps = 30;
  double seconds_decode = 0, seconds_render = 0;
};

// Checks the job's numbers and files, creates out_dir, then decodes and renders.
RenderedInput render_stage(vk::Context& ctx, const RenderJob& job, const std::function<void(const std::string&)>& say);

// Frames of the render that show nothing of the scene (no visible pixel in the mask). When every frame after the
// first is empty the camera left the scene at once (wrong units, magnitude, convention or depth) and a run would
// invent the whole clip: an error, before any long work. When only some are, a warning to the log naming them
// (a path may pass a gap on purpose; the model then fills those frames from the others) and where the user sees
// the mask ("mask.mp4", or a clip run's result view). `radius` is the orbit radius the path was built with (named
// in the error).
void check_visibility(const HostTensor& mask, const RenderJob& job, double radius,
                      const std::function<void(const std::string&)>& say, const std::string& where_the_mask_is);

// The camera a job renders with: its --intrinsics, else the default (square pixels under crop, the official
// per-axis scaling under squash). Throws dvs::Error for incomplete or non-positive values.
geometry::Intrinsics job_intrinsics(const RenderJob& job);

// Why the job's size cannot render on this device's limits (geometry/splat_memory.hpp: one frame's accumulation
// over a binding or an allocation, a frame's dispatch over the group counts), and what helps; nothing when it fits.
std::optional<std::string> render_limits_problem(const RenderJob& job, const vk::DeviceCaps& device);

// Validates and creates the output folder (clear error when it cannot be written).
void prepare_out_dir(const std::filesystem::path& dir);

// A {0,1} mask [F,H,W] as a black/white video in [−1,1].
HostTensor mask_as_video(const HostTensor& mask);

}  // namespace dvs
