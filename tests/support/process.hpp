// Runs a shell command as a user would and captures its exit code and combined output.
#pragma once
#include <string>

namespace dvs::test {

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

CommandResult run_command(const std::string& cmd);

// Path of a program this build produced ("dvs", "dvs-weights").
std::string program(const std::string& name);

}  // namespace dvs::test
