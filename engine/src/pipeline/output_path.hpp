// Where a job will write, checked before its work (seconds or hours of it): a folder that exists and may be
// written, or can be created below one; a file whose folder is such a folder and that can be created there.
// The same rules for `dvs run --out` (the preflight), `dvs depth --out` and the depth cache, each problem named
// with the option that fixes it.
#pragma once
#include <filesystem>
#include <optional>
#include <string>

namespace dvs {

// What is wrong with writing into folder `dir` (created if missing), or nothing. `fix` ends the message
// ("give another --out").
std::optional<std::string> folder_write_problem(const std::filesystem::path& dir, const std::string& fix);

// What is wrong with writing `file` (atomically: a temporary file beside it, renamed into place), or nothing:
// its folder as folder_write_problem, the path not a folder itself, and, when the folder exists, a file really
// created there (and removed), so a read-only or full file system is found now rather than after the work.
std::optional<std::string> file_write_problem(const std::filesystem::path& file, const std::string& fix);

}  // namespace dvs
