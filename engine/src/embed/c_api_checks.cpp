// dvs/dvs.h: the checks before any work (dvs/preflight.hpp) and the memory plan (dvs/plan.hpp) from C. Both give a
// text report copied into the caller's buffer with the size it needs, and a few numbers.
#include <algorithm>
#include <cstddef>
#include <cstring>

#include "dvs/devices.hpp"
#include "dvs/plan.hpp"
#include "dvs/preflight.hpp"
#include "embed/c_api_guard.hpp"
#include "embed/c_api_options.hpp"

using namespace dvs::capi;

namespace {

// "problem: ..." lines, then "note: ..." lines, in the C structs' names.
void report_out(const dvs::PreflightReport& r, int32_t* problems, char* report, size_t size, size_t* needed,
                const char* call) {
  std::string text;
  for (const std::string& p : r.problems) text += "problem: " + p + "\n";
  for (const std::string& n : r.notes) text += "note: " + n + "\n";
  if (problems) *problems = int32_t(r.problems.size());
  copy_out(c_option_names(text), report, size, needed, call, "report");
}

std::string text(const char* s) { return s ? s : ""; }

// The size of the first dvs_plan_request (dvs/dvs.h: structs that can grow).
constexpr size_t kFirstPlanRequestSize = offsetof(dvs_plan_request, depth_frame_width) + sizeof(int32_t);

}  // namespace

extern "C" {

dvs_status dvs_preflight_pipeline(const dvs_pipeline_options* options, int32_t* problems, char* report, size_t size,
                                  size_t* needed) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_preflight_pipeline";
    require(options, call, "options");
    report_out(dvs::preflight(run_options(*options, call), dvs::JobKind::run), problems, report, size, needed, call);
  });
}

dvs_status dvs_preflight_render(const dvs_render_options* options, int32_t* problems, char* report, size_t size,
                                size_t* needed) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_preflight_render";
    require(options, call, "options");
    report_out(dvs::preflight_render(render_job(*options, call)), problems, report, size, needed, call);
  });
}

dvs_status dvs_plan_request_default(dvs_plan_request* out) {
  return guarded(DVS_ERROR_INVALID_ARGUMENT, [&] {
    require(out, "dvs_plan_request_default", "out");
    static const dvs::MemoryPlanRequest d;
    static const std::string weights = d.weights;
    *out = {};
    out->struct_size = sizeof(dvs_plan_request);
    out->frames = int32_t(d.frames), out->height = int32_t(d.height), out->width = int32_t(d.width);
    out->alignment = d.alignment;
    out->depth_input_size = d.depth_input_size;
    out->weights = weights.c_str();
    out->upload_bytes_per_second = d.upload_bytes_per_second;
  });
}

dvs_status dvs_plan_run_memory(const dvs_plan_request* request, dvs_plan_result* result, int32_t json, char* report,
                               size_t size, size_t* needed) {
  return guarded(DVS_ERROR_FILE, [&] {
    const char* call = "dvs_plan_run_memory";
    require(request, call, "request");
    const dvs_plan_request q =
        read_filled(*request, dvs_plan_request_default, kFirstPlanRequestSize, "dvs_plan_request", call);
    if (result && result->struct_size < sizeof(size_t))
      throw dvs::UsageError(std::string(call) + ": dvs_plan_result.struct_size is " + std::to_string(result->struct_size) +
                            ": set it to sizeof(dvs_plan_result)");
    require(q.model, call, "request->model");
    if (json != 0 && json != 1)
      throw dvs::UsageError(std::string(call) + ": json must be 0 (the table) or 1 (JSON), got " + std::to_string(json));
    if (q.device && q.limits)
      throw dvs::UsageError(std::string(call) + ": give request->device or request->limits, not both");
    dvs::MemoryPlanRequest r;
    r.model = q.model;
    r.frames = q.frames, r.height = q.height, r.width = q.width;
    if (q.budget) r.budget = q.budget;
    r.alignment = q.alignment;
    if (q.device) r.limits = dvs::device_limits(q.device);
    if (q.limits) r.limits = dvs::profile_limits(q.limits);
    r.depth_model = text(q.depth_model);
    r.depth_input_size = q.depth_input_size;
    r.depth_frame_height = q.depth_frame_height, r.depth_frame_width = q.depth_frame_width;
    if (q.weights) r.weights = q.weights;
    r.upload_bytes_per_second = q.upload_bytes_per_second;
    const dvs::MemoryPlanReport plan = dvs::plan_run_memory(r);
    if (result) {
      dvs_plan_result out{};
      out.struct_size = std::min(result->struct_size, sizeof(dvs_plan_result));
      out.checked = plan.checked ? 1 : 0;
      out.runs = plan.runs ? 1 : 0;
      out.weights_bytes = plan.weights_bytes;
      out.run_peak_bytes = plan.run_peak_bytes;
      std::memcpy(static_cast<void*>(result), &out, out.struct_size);  // only what the caller's struct holds
    }
    copy_out(json ? plan.json : plan.table, report, size, needed, call, "text");
  });
}

}  // extern "C"
