#include "support/process.hpp"

#include <spawn.h>
#include <unistd.h>
#include <sys/wait.h>

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <cstdlib>

namespace dvs::test {

CommandResult run_command(const std::string& cmd, ValidationMessages validation_messages) {
  CommandResult r;
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf{};
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  // A program runs with the validation layer when DVS_VALIDATION=1 is set (tests/run_with_sync_validation.sh sets
  // it) and prints each message so (vk/context.cpp); a message fails the test, as one in the test's own process
  // does (support/gpu.cpp).
  if (validation_messages == ValidationMessages::fail)
    for (const char* tag : {"[validation error] ", "[validation warning] "})
      if (const size_t at = r.output.find(tag); at != std::string::npos)
        ADD_FAILURE() << "the validation layer reported in `" << cmd
                      << "`: " << r.output.substr(at, r.output.find('\n', at) - at);
  return r;
}

int start_command(const std::string& cmd) {
  const std::string line = "exec " + cmd;
  const char* argv[] = {"/bin/sh", "-c", line.c_str(), nullptr};
  pid_t pid = -1;
  if (posix_spawn(&pid, "/bin/sh", nullptr, nullptr, const_cast<char* const*>(argv), environ) != 0) return -1;
  return int(pid);
}

int wait_command(int pid) {
  int status = 0;
  if (waitpid(pid_t(pid), &status, 0) < 0) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// DVS_BIN_DIR in the environment: where the programs are when the tests run from a relocated bundle
// (bench/gpu/run.sh); else this build's folder.
std::string program(const std::string& name) {
  const char* e = std::getenv("DVS_BIN_DIR");
  return std::string(e && *e ? e : DVS_BIN_DIR) + "/" + name;
}

}  // namespace dvs::test
