// Faults injected on request, so tests can prove what a real out-of-memory, lost device or failed disk write
// does to a run. One environment variable, read once per process:
//
//   DVS_FAULTS="alloc=N"          the Nth device memory allocation fails with VK_ERROR_OUT_OF_DEVICE_MEMORY
//   DVS_FAULTS="submit=N"         the Nth queue submission reports VK_ERROR_DEVICE_LOST
//   DVS_FAULTS="write=N:ENOSPC"   the Nth file write fails with ENOSPC (disk full); "write=N:EIO": an I/O error
//   comma-separated to combine ("alloc=40,write=3:EIO"); N counts from 1 over the whole process.
//   DVS_FAULTS_TRACE=FILE        appends one line per counted event: "<kind> <N> stage=<stage> <where>", so a
//                                test can pick N for every stage (works with or without DVS_FAULTS).
//
// Unset, each hook costs one test of a cached flag. The hooks sit where the real call's result is checked, so
// an injected fault takes the same error path as a real one.
#pragma once
#include <filesystem>
#include <string_view>

namespace dvs::faults {

enum class Kind { alloc, submit, write };

// Counts one event of `kind` (traced with `where`); true when DVS_FAULTS asks this one to fail.
bool fail_now(Kind kind, std::string_view where);

// A file write about to be finished: the errno it must fail with (ENOSPC or EIO), 0 to write normally.
int write_error(const std::filesystem::path& file);

// The stage now running, named in the trace: a run stage ("render", "encode", ...), "after-<stage>" between
// two, "start-up" before the first. One word. Free when neither variable is set.
void set_stage(std::string_view stage);

}  // namespace dvs::faults
