// dvs run's own argument checks, for the harnesses whose readers produce dvs run arguments (a batch job, a
// run.json): the arguments are matched against dvs run's options (engine/cli/options.hpp) and, when the
// required ones are there, turned into RunOptions (parse_run_options), as the dvs program does next.
#pragma once
#include <string>
#include <vector>

#include "args.hpp"
#include "options.hpp"
#include "run_command.hpp"

namespace dvs::fuzz {

inline void check_run_arguments(const std::vector<std::string>& argv) {
  cli::Args a("run", cli::CommandHelp{"dvs run (fuzz harness)", "", ""}, cli::run_option_groups());
  a.parse(argv);
  if (a.help()) return;
  for (const char* key : {"video", "out", "model"})
    if (!a.has(key)) return;
  if (!a.has("depth") && !a.has("depth-model")) return;
  (void)cli::parse_run_options(a);
}

}  // namespace dvs::fuzz
