// dvs/dvs.h: the job calls over dvs::Job (the option structs are read by embed/c_api_options.cpp).
#include "embed/c_api_guard.hpp"
#include "embed/c_api_handles.hpp"
#include "embed/c_api_options.hpp"

using namespace dvs::capi;

extern "C" {

dvs_status dvs_job_start_render(const dvs_render_options* options, dvs_job** out) {
  return start_job(out, "dvs_job_start_render", "render", [&] {
    require(options, "dvs_job_start_render", "options");
    return dvs::start_render(render_job(*options, "dvs_job_start_render"));
  });
}

dvs_status dvs_job_start_pipeline(const dvs_pipeline_options* options, dvs_job** out) {
  return start_job(out, "dvs_job_start_pipeline", "pipeline", [&] {
    require(options, "dvs_job_start_pipeline", "options");
    return dvs::start_pipeline(run_options(*options, "dvs_job_start_pipeline"));
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
    copy_out(c_option_names(job->job.error()), buffer, size, needed, "dvs_job_error", "buffer");
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
