// Runs a shell command as a user would and captures its exit code and combined output.
#pragma once
#include <string>

namespace dvs::test {

struct CommandResult {
  int exit_code = -1;
  std::string output;  // stdout and stderr together
};

// A validation-layer message in the output (a program runs with the layer under DVS_VALIDATION=1) fails the
// calling test, unless `validation_messages` is `expected` (a test about those messages).
enum class ValidationMessages { fail, expected };
CommandResult run_command(const std::string& cmd, ValidationMessages validation_messages = ValidationMessages::fail);

// Starts `cmd` in the background through /bin/sh (exec'd, so the pid is the program's own) and returns its
// pid, for tests that signal a running program. The command redirects its own output.
int start_command(const std::string& cmd);
// Waits for a started command: its exit code, or 128 + the signal that ended it.
int wait_command(int pid);

// Path of a program this build produced ("dvs", "dvs-weights").
std::string program(const std::string& name);

}  // namespace dvs::test
