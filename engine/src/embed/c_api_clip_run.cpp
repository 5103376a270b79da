// dvs/dvs.h: a whole run on a clip in memory (dvs/clip_run.hpp) from C, blocking or as a job, and the latent's shape
// for sizing its buffer. Pointers and sizes are checked here, the options and views by the run (each
// DVS_ERROR_INVALID_ARGUMENT naming the argument, option or view); the clip's values by the run (DVS_ERROR_FILE).
#include <cstring>

#include "dvs/clip_run.hpp"
#include "embed/c_api_guard.hpp"
#include "embed/c_api_handles.hpp"
#include "embed/c_api_options.hpp"
#include "pipeline/clip_input.hpp"

using namespace dvs::capi;

namespace {

// 16·F row-major doubles as F poses (none for NULL: the options' trajectory).
std::vector<dvs::Pose> pose_list(const double* poses, int64_t F) {
  std::vector<dvs::Pose> list;
  if (!poses) return list;
  list.resize(size_t(F));
  for (int64_t i = 0; i < F; ++i) std::memcpy(list[size_t(i)].m.data(), poses + 16 * i, 16 * sizeof(double));
  return list;
}

// The C arguments of a clip run as the C++ call's views.
struct ClipCall {
  dvs::RunOptions options;
  dvs::ClipView clip;
  dvs::ClipResultViews out;
};

ClipCall clip_call(const char* call, const dvs_context* context, const dvs_pipeline_options* options,
                   const uint8_t* frames, int32_t count, int32_t height, int32_t width, const float* depth,
                   const double* poses, uint8_t* output, float* mask, float* latent, size_t latent_floats) {
  require(context, call, "context");
  require(options, call, "options");
  require(frames, call, "frames");
  require(depth, call, "depth");
  require(output, call, "output");
  check_clip_size(count, height, width, call);
  // The first real cause of a clip the model cannot take, before anything sized from it (the latent).
  dvs::check_clip_size(count, height, width, std::string(call) + ": count", std::string(call) + ": height/width");
  ClipCall c;
  c.options = run_options(*options, call);
  const int64_t F = count, H = height, W = width;
  c.clip.frames = {const_cast<uint8_t*>(frames), dvs::ElementType::u8, {F, H, W, 3}};
  c.clip.depth = {const_cast<float*>(depth), dvs::ElementType::f32, {F, H, W}};
  c.clip.poses = pose_list(poses, F);
  c.out.output = {output, dvs::ElementType::u8, {F, H, W, 3}};
  if (mask) c.out.mask = {mask, dvs::ElementType::f32, {F, H, W}};
  if (latent) {
    const std::vector<int64_t> shape = dvs::clip_latent_shape(c.options.model, F, H, W);
    const size_t floats = size_t(shape[0] * shape[1] * shape[2] * shape[3]);
    if (latent_floats != floats)
      throw dvs::UsageError(std::string(call) + ": latent_floats is " + std::to_string(latent_floats) + " but the latent is [" +
                            std::to_string(shape[0]) + "," + std::to_string(shape[1]) + "," + std::to_string(shape[2]) +
                            "," + std::to_string(shape[3]) + "] = " + std::to_string(floats) +
                            " floats (dvs_clip_latent_shape gives the shape)");
    c.out.latent = {latent, dvs::ElementType::f32, shape};
  }
  return c;
}

}  // namespace

extern "C" {

dvs_status dvs_clip_latent_shape(const dvs_pipeline_options* options, int32_t count, int32_t height, int32_t width,
                                 int64_t shape[4]) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_clip_latent_shape";
    require(options, call, "options");
    require(shape, call, "shape");
    require(options->model, call, "options->model");
    check_clip_size(count, height, width, call);
    dvs::check_clip_size(count, height, width, std::string(call) + ": count", std::string(call) + ": height/width");
    const std::vector<int64_t> s = dvs::clip_latent_shape(run_options(*options, call).model, count, height, width);
    std::copy(s.begin(), s.end(), shape);
  });
}

dvs_status dvs_run_pipeline_clip(dvs_context* context, const dvs_pipeline_options* options, const uint8_t* frames,
                                 int32_t count, int32_t height, int32_t width, const float* depth, const double* poses,
                                 uint8_t* output, float* mask, float* latent, size_t latent_floats,
                                 dvs_progress_fn progress, void* user) {
  return guarded(DVS_ERROR_FILE, [&] {
    const ClipCall c = clip_call("dvs_run_pipeline_clip", context, options, frames, count, height, width, depth, poses,
                                 output, mask, latent, latent_floats);
    CProgress p{progress, user};
    dvs::run_pipeline(*context->context, c.options, c.clip, c.out, p.fn(), p.cancelled());
  });
}

dvs_status dvs_run_pipeline_clip_device(dvs_context* context, const dvs_pipeline_options* options,
                                        dvs_buffer_range frames, int32_t count, int32_t height, int32_t width,
                                        dvs_buffer_range depth, const double* poses, dvs_buffer_range output,
                                        dvs_buffer_range mask, dvs_buffer_range latent, dvs_progress_fn progress,
                                        void* user) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_run_pipeline_clip_device";
    require(context, call, "context");
    require(options, call, "options");
    check_clip_size(count, height, width, call);
    dvs::check_clip_size(count, height, width, std::string(call) + ": count", std::string(call) + ": height/width");
    const dvs::RunOptions o = run_options(*options, call);
    const int64_t F = count, H = height, W = width;
    dvs::ClipDeviceView clip;
    clip.frames = {frames.buffer, frames.offset, dvs::ElementType::u8, {F, H, W, 3}};
    clip.depth = {depth.buffer, depth.offset, dvs::ElementType::f32, {F, H, W}};
    clip.poses = pose_list(poses, F);
    dvs::ClipResultDeviceViews out;
    out.output = {output.buffer, output.offset, dvs::ElementType::u8, {F, H, W, 3}};
    out.mask = {mask.buffer, mask.offset, dvs::ElementType::f32, {F, H, W}};
    if (latent.buffer) out.latent = {latent.buffer, latent.offset, dvs::ElementType::f32, dvs::clip_latent_shape(o.model, F, H, W)};
    CProgress p{progress, user};
    dvs::run_pipeline(*context->context, o, clip, out, p.fn(), p.cancelled());
  });
}

dvs_status dvs_job_start_pipeline_clip(dvs_context* context, const dvs_pipeline_options* options,
                                       const uint8_t* frames, int32_t count, int32_t height, int32_t width,
                                       const float* depth, const double* poses, uint8_t* output, float* mask,
                                       float* latent, size_t latent_floats, dvs_job** out) {
  const char* call = "dvs_job_start_pipeline_clip";
  return start_job(out, call, "pipeline", [&] {
    const ClipCall c =
        clip_call(call, context, options, frames, count, height, width, depth, poses, output, mask, latent, latent_floats);
    return dvs::start_pipeline(*context->context, c.options, c.clip, c.out);
  });
}

}  // extern "C"
