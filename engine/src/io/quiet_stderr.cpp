// The quiet-or-verbose choice for the third-party libraries' logs (io/third_party_logs.hpp) and QuietStderr.
#include <fcntl.h>
#include <unistd.h>

#include <cstdio>

#include "io/third_party_logs.hpp"

namespace dvs {
namespace {

bool g_verbose = false;
bool g_chosen = false;

}  // namespace

void remember_third_party_logs(bool verbose) {
  g_verbose = verbose;
  g_chosen = true;
}

bool third_party_logs_verbose() { return g_verbose; }
bool third_party_logs_chosen() { return g_chosen; }

QuietStderr::QuietStderr() {
  if (g_verbose) return;
  std::fflush(stderr);
  const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (null < 0) return;
  saved_ = ::dup(2);
  if (saved_ >= 0) ::dup2(null, 2);
  ::close(null);
}

QuietStderr::~QuietStderr() {
  if (saved_ < 0) return;
  std::fflush(stderr);
  ::dup2(saved_, 2);
  ::close(saved_);
}

}  // namespace dvs
