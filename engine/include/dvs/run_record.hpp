// run.json, which every `dvs run` writes next to its outputs: every setting actually used, so a run can be
// understood and repeated (`dvs run --from run.json`).
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "dvs/api.hpp"

namespace dvs {

// A run.json turned back into `dvs run` arguments ("--video", "/abs/v.mp4", ...): every input and setting the
// run used, so that running them repeats it. Throws dvs::Error naming the file and the key when it is not a
// run.json dvs wrote.
DVS_API std::vector<std::string> run_record_arguments(const std::filesystem::path& run_json);

}  // namespace dvs
