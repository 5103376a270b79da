#include "interrupt.hpp"

#include <csignal>
#include <ctime>
#include <unistd.h>

namespace dvs::cli {
namespace {

volatile std::sig_atomic_t g_interrupted = 0;
// When the first signal arrived (CLOCK_MONOTONIC, ns); written once in the handler before g_interrupted.
volatile long long g_first_ns = 0;

long long now_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);  // async-signal-safe
  return static_cast<long long>(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}

// write(2) is async-signal-safe; stdio is not.
template <size_t N>
void say(const char (&text)[N]) {
  [[maybe_unused]] const ssize_t n = ::write(2, text, N - 1);
}

void on_signal(int sig) {
  const long long t = now_ns();
  if (!g_interrupted) {
    g_first_ns = t;
    g_interrupted = 1;
    say(kStoppingMessage);  // at once: the job polls the flag within seconds, but the user must see it was heard
    return;
  }
  // A repeat within the grace period is the same Ctrl-C (a terminal or `timeout -s INT` may deliver two
  // at once): the clean stop goes on. Later, the user insists: stop now.
  if (t - g_first_ns < kSameInterruptNs) return;
  say("dvs: stopped at once (second Ctrl-C); partial outputs may remain\n");
  std::signal(sig, SIG_DFL);
  std::raise(sig);
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
