// How the library's messages (dvs::Error, preflight problems, warnings to the log handler of dvs/logs.hpp) name
// the options of a run or a render. A library user reads the field: "RunOptions::strength must be in (0, 1]",
// "RenderJob::trajectory pan_left:180: frames 1-8 show nothing"; the C API rewrites those to its own structs
// ("dvs_pipeline_options.strength", "dvs_render_options.trajectory"). The dvs program names its flags instead
// ("--strength", "--trajectory") and sets that once at its start.
#pragma once

#include "dvs/api.hpp"

namespace dvs {

enum class OptionNames {
  fields,        // RunOptions::strength, RenderJob::trajectory (the default)
  command_line,  // --strength, --trajectory: the dvs program's flags
};

// Process-wide; call before the work whose messages it concerns.
DVS_API void set_option_names(OptionNames names);

}  // namespace dvs
