#include "support/process.hpp"

#include <sys/wait.h>

#include <array>
#include <cstdio>

namespace dvs::test {

CommandResult run_command(const std::string& cmd) {
  CommandResult r;
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf{};
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string program(const std::string& name) { return std::string(DVS_BIN_DIR) + "/" + name; }

}  // namespace dvs::test
