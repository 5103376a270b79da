// What `dvs run`, `dvs invert` and `dvs batch` share: the run options read from their arguments (options.hpp
// declares them, for the command line and for batch jobs) and executing one run with progress output and
// Ctrl-C handling.
#pragma once
#include <string>
#include <vector>

#include "args.hpp"
#include "dvs/pipeline.hpp"
#include "progress.hpp"

namespace dvs::cli {

// RunOptions from parsed arguments. --video, --depth, --model and --out are required; --prompt is read when
// present (the caller requires it where it matters).
RunOptions parse_run_options(const Args& a);
// argv with `--from RUN.json` replaced by the arguments that run.json records, placed before the rest so the
// options given next to --from override them. argv itself when there is no --from.
std::vector<std::string> with_recorded_run(const std::vector<std::string>& argv);

// One line on stderr with each stage's seconds (nothing with --quiet).
void print_stage_times(ProgressMode mode, const std::vector<StageTime>& stages, bool inversion_from_cache);

// Runs the whole pipeline, printing progress, stage times and the files written.
int execute_run(const RunOptions& o, ProgressMode mode);

}  // namespace dvs::cli
