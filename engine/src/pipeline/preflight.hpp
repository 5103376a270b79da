// The preflight (dvs/preflight.hpp: the checks and their report, public) as the pipeline's stages call it.
#pragma once
#include "dvs/preflight.hpp"

namespace dvs {

// Throws dvs::Error with report.message() when there is any problem.
void require_preflight(const RunOptions& o, JobKind kind);

}  // namespace dvs
