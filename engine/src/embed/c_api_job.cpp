// dvs/dvs.h: the job calls over dvs::Job, and the C option structs with their defaults (taken from the C++
// structs' own defaults, so the two never drift apart).
#include "embed/c_api_guard.hpp"
#include "embed/c_api_handles.hpp"
#include "embed/c_api_options.hpp"

using namespace dvs::capi;

namespace {

std::string text(const char* s) { return s ? s : ""; }

dvs::RenderJob render_job(const dvs_render_options& o) {
  dvs::RenderJob j;
  j.video = text(o.video);
  j.depth = text(o.depth);
  j.depth_model = text(o.depth_model);
  j.out_dir = text(o.out_dir);
  if (o.trajectory) j.trajectory = o.trajectory;
  j.device = text(o.device);
  j.frames = o.frames;
  j.height = o.height, j.width = o.width;
  j.metric_depth = o.metric_depth != 0;
  j.hard_points = o.hard_points != 0;
  j.depth_input_size = o.depth_input_size;
  return j;
}

}  // namespace

dvs::RunOptions dvs::capi::run_options(const dvs_pipeline_options& options) {
  dvs::RunOptions r;
  r.render = render_job(options.render);
  r.model = text(options.model);
  r.prompt = text(options.prompt);
  r.negative_prompt = text(options.negative_prompt);
  if (options.preset) r.preset = options.preset;
  r.cache_dir = text(options.cache_dir);
  r.lora = text(options.lora);
  r.steps = options.steps, r.inversion_steps = options.inversion_steps;
  r.strength = options.strength, r.k = options.k, r.delta = options.delta, r.guidance = options.guidance;
  r.lora_scale = options.lora_scale;
  r.seed = options.seed;
  r.use_cache = options.use_cache != 0;
  return r;
}

dvs_status dvs::capi::start_job(dvs_job** out, const char* call, const char* kind,
                                const std::function<dvs::Job()>& begin) {
  return guarded(DVS_ERROR_FILE, [&] {
    require(out, call, "out");
    *out = nullptr;
    auto handle = std::unique_ptr<dvs_job>(new dvs_job{begin(), kind});
    *out = handle.release();
  });
}

extern "C" {

dvs_status dvs_render_options_default(dvs_render_options* out) {
  return guarded(DVS_ERROR_INVALID_ARGUMENT, [&] {
    require(out, "dvs_render_options_default", "out");
    static const dvs::RenderJob d;
    static const std::string trajectory = d.trajectory;
    *out = {};
    out->trajectory = trajectory.c_str();
    out->frames = d.frames;
    out->height = d.height, out->width = d.width;
    out->metric_depth = d.metric_depth, out->hard_points = d.hard_points;
    out->depth_input_size = d.depth_input_size;
  });
}

dvs_status dvs_pipeline_options_default(dvs_pipeline_options* out) {
  return guarded(DVS_ERROR_INVALID_ARGUMENT, [&] {
    require(out, "dvs_pipeline_options_default", "out");
    static const dvs::RunOptions d;
    static const std::string preset = d.preset;
    *out = {};
    if (const dvs_status s = dvs_render_options_default(&out->render); s != DVS_OK) throw dvs::Error(dvs_last_error());
    out->preset = preset.c_str();
    out->steps = d.steps, out->inversion_steps = d.inversion_steps;
    out->strength = d.strength, out->k = d.k, out->delta = d.delta, out->guidance = d.guidance;
    out->lora_scale = d.lora_scale;
    out->seed = d.seed;
    out->use_cache = d.use_cache;
  });
}

dvs_status dvs_job_start_render(const dvs_render_options* options, dvs_job** out) {
  return start_job(out, "dvs_job_start_render", "render", [&] {
    require(options, "dvs_job_start_render", "options");
    return dvs::start_render(render_job(*options));
  });
}

dvs_status dvs_job_start_pipeline(const dvs_pipeline_options* options, dvs_job** out) {
  return start_job(out, "dvs_job_start_pipeline", "pipeline", [&] {
    require(options, "dvs_job_start_pipeline", "options");
    return dvs::start_pipeline(run_options(*options));
  });
}

dvs_status dvs_job_start_depth(const char* video, const char* model, const char* out_file, int32_t input_size,
                               int32_t frames, dvs_job** out) {
  return start_job(out, "dvs_job_start_depth", "depth", [&] {
    const char* call = "dvs_job_start_depth";
    require(video, call, "video");
    require(model, call, "model");
    require(out_file, call, "out_file");
    dvs::DepthJob j;
    j.video = video;
    j.model = model;
    if (input_size) j.input_size = input_size;
    j.frames = frames;
    return dvs::start_depth(j, out_file);
  });
}

dvs_status dvs_job_poll(const dvs_job* job, dvs_job_state* out) {
  return guarded(DVS_ERROR_INTERNAL, [&] {
    require(job, "dvs_job_poll", "job");
    require(out, "dvs_job_poll", "out");
    switch (job->job.poll()) {
      case dvs::JobState::running: *out = DVS_JOB_RUNNING; break;
      case dvs::JobState::succeeded: *out = DVS_JOB_SUCCEEDED; break;
      case dvs::JobState::failed: *out = DVS_JOB_FAILED; break;
      case dvs::JobState::cancelled: *out = DVS_JOB_CANCELLED; break;
    }
  });
}

dvs_status dvs_job_progress(const dvs_job* job, char* stage_buffer, size_t stage_size, size_t* stage_needed,
                            int32_t* step, int32_t* total) {
  return guarded(DVS_ERROR_INTERNAL, [&] {
    require(job, "dvs_job_progress", "job");
    const dvs::JobProgress p = job->job.progress();
    if (step) *step = p.step;
    if (total) *total = p.total;
    copy_out(p.stage, stage_buffer, stage_size, stage_needed, "dvs_job_progress", "stage_buffer");
  });
}

dvs_status dvs_job_wait(dvs_job* job, int64_t timeout_ms, int32_t* finished) {
  return guarded(DVS_ERROR_INTERNAL, [&] {
    require(job, "dvs_job_wait", "job");
    bool done = true;
    if (timeout_ms < 0) job->job.wait();
    else done = job->job.wait_for(std::chrono::milliseconds(timeout_ms));
    if (finished) *finished = done ? 1 : 0;
  });
}

dvs_status dvs_job_cancel(dvs_job* job) {
  return guarded(DVS_ERROR_INTERNAL, [&] {
    require(job, "dvs_job_cancel", "job");
    job->job.cancel();
  });
}

dvs_status dvs_job_error(const dvs_job* job, char* buffer, size_t size, size_t* needed) {
  return guarded(DVS_ERROR_INTERNAL, [&] {
    require(job, "dvs_job_error", "job");
    copy_out(job->job.error(), buffer, size, needed, "dvs_job_error", "buffer");
  });
}

dvs_status dvs_job_result(dvs_job* job) {
  if (!job) return fail(DVS_ERROR_INVALID_ARGUMENT, "dvs_job_result: job is NULL");
  // The job's own failure is the status here: a dvs::Error of the work is most likely its inputs.
  return guarded(DVS_ERROR_FILE, [&] {
    if (job->kind == "render") job->job.render_summary();
    else if (job->kind == "pipeline") job->job.run_report();
    else job->job.depth_summary();
  });
}

dvs_status dvs_job_destroy(dvs_job* job) {
  return guarded(DVS_ERROR_INTERNAL, [&] { delete job; });
}

}  // extern "C"
