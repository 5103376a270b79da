// The jobs file of `dvs batch` (JSON lines): read into jobs, and one job's JSON object turned into dvs run
// arguments. Apart from cmd_batch.cpp so the fuzz harness (tests/fuzz/fuzz_batch_jobs.cpp) drives the same code.
#pragma once
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace dvs::cli {

struct Job {
  int index = 0, line = 0;  // index among jobs (what shards split), 1-based line in the file
  nlohmann::json spec;
};

// Every job of the file: one JSON object per line; blank lines and lines starting with # are not jobs. Throws
// dvs::Error naming the file and line of the first line that is not a JSON object.
std::vector<Job> read_jobs(const std::filesystem::path& file);

// A job's JSON object as dvs run arguments: each key must name one of dvs run's options (the declarations the
// command line is read with), a flag's value is true or false. Throws dvs::Error naming the key.
std::vector<std::string> job_arguments(const nlohmann::json& spec);

}  // namespace dvs::cli
