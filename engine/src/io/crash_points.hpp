// Crash points: named places (stage boundaries, diffusion steps, cache writes, the renames that publish a job's
// files) where a test may kill the process, to show that a rerun after a SIGKILL at any of them recovers.
// Test-only switches, read once per process:
//   DVS_CRASH_TRACE=FILE  every point reached appends "<n> <name>\n" to FILE (n counts from 1 in this process);
//   DVS_CRASH_AT=N        the N-th point reached is written to the trace (when set) and the process raises
//                         SIGKILL there: no destructor, no atexit handler, no flush of stdio buffers runs.
// Unset (every real run), a crash point costs one test of a flag read from the environment once.
#pragma once
#include <string_view>

namespace dvs {

// Reaches the crash point named "<kind>[:<detail>][:<number>]" (e.g. "step:sample:3", "publish-before:output.mp4");
// no spaces or newlines. The name is put together only when a switch is set.
void crash_point(std::string_view kind, std::string_view detail = {}, long number = -1);

}  // namespace dvs
