// The jobs file of `dvs batch` (engine/cli/batch_jobs.hpp): JSON lines read into jobs, each job's keys turned
// into dvs run arguments, then those matched against dvs run's options and read as RunOptions, as dvs batch
// checks a file before running anything (preflight, which opens the files a job names, is left out).
#include "batch_jobs.hpp"
#include "dvs/error.hpp"
#include "harness_input.hpp"
#include "run_arguments.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto file = dvs::fuzz::write_scratch("jobs.jsonl", dvs::fuzz::as_text(data, size));
  try {
    for (const dvs::cli::Job& job : dvs::cli::read_jobs(file)) {
      try {
        dvs::fuzz::check_run_arguments(dvs::cli::job_arguments(job.spec));
      } catch (const dvs::Error&) {  // dvs batch reports each job's problem and goes on to the next job
      }
    }
  } catch (const dvs::Error&) {
  }
  return 0;
}
