#include "interrupt.hpp"

#include <csignal>

namespace dvs::cli {
namespace {

volatile std::sig_atomic_t g_interrupted = 0;

void on_signal(int sig) {
  if (g_interrupted) {  // the second signal: the user insists, stop now
    std::signal(sig, SIG_DFL);
    std::raise(sig);
    return;
  }
  g_interrupted = 1;
}

}  // namespace

void install_interrupt_handler() {
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

bool interrupted() { return g_interrupted != 0; }

}  // namespace dvs::cli
