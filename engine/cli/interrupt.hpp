// Ctrl-C and SIGTERM: the first one sets a flag that long jobs poll (at stage boundaries, before every
// diffusion step and between the bounded GPU submissions of one recording) so they stop cleanly and remove their partial outputs. Another signal within half a second of
// the first is the same interruption (two often arrive together); one after that ends the process at once.
#pragma once

namespace dvs::cli {

void install_interrupt_handler();
bool interrupted();

// The exit code of a job stopped by a signal (128 + SIGINT, as shells report it).
constexpr int kInterruptedExitCode = 130;

// Written to stderr by the first signal's handler, the moment it arrives.
inline constexpr char kStoppingMessage[] = "\ndvs: stopping… (finishing the current step; Ctrl-C again to quit at once)\n";

// Signals this close to the first one (nanoseconds) count as the same Ctrl-C.
constexpr long long kSameInterruptNs = 500'000'000LL;

}  // namespace dvs::cli
