// What the C API's calls share beyond the guard (embed/c_api_guard.hpp): the pipeline options' conversion and the
// start of a job handle, used by the file jobs (c_api_job.cpp) and the clip run (c_api_clip_run.cpp).
#pragma once
#include <functional>

#include "dvs/dvs.h"
#include "dvs/job.hpp"
#include "dvs/pipeline.hpp"

namespace dvs::capi {

// dvs_pipeline_options as dvs::RunOptions (NULL strings = unset).
RunOptions run_options(const dvs_pipeline_options& options);

// *out = a job handle of `kind` ("render", "pipeline", "depth") around what `begin` starts; errors as guarded().
dvs_status start_job(dvs_job** out, const char* call, const char* kind, const std::function<Job()>& begin);

}  // namespace dvs::capi
