// The dvs sub-commands; each returns the process exit code and throws dvs::Error for user errors.
#pragma once
#include <string>
#include <vector>

namespace dvs::cli {

int run_info(const std::vector<std::string>& args);
int run_render(const std::vector<std::string>& args);
int run_run(const std::vector<std::string>& args);
int run_demo(const std::vector<std::string>& args);
int run_invert(const std::vector<std::string>& args);
int run_encode_prompt(const std::vector<std::string>& args);
int run_batch(const std::vector<std::string>& args);
int run_plan(const std::vector<std::string>& args);
int run_depth(const std::vector<std::string>& args);
int run_cache(const std::vector<std::string>& args);

}  // namespace dvs::cli
