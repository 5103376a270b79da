// Ctrl-C and SIGTERM: the first one sets a flag that long jobs poll (at stage boundaries and before every
// diffusion step) so they stop cleanly and remove their partial outputs; a second one ends the process at once.
#pragma once

namespace dvs::cli {

void install_interrupt_handler();
bool interrupted();

// The exit code of a job stopped by a signal (128 + SIGINT, as shells report it).
constexpr int kInterruptedExitCode = 130;

}  // namespace dvs::cli
