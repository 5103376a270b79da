// What the harnesses share. A harness hands its input to a production reader; a reader that takes only a path
// gets the input as a file in a scratch folder of the process's own (one write per input, on tmpfs when
// /dev/shm exists, so a run stays fast). A reader of several files (a model folder) gets the input cut into
// parts at kPartSeparator. Only dvs::Error may leave a reader: any other exception escapes the harness and
// libFuzzer reports it as a crash.
#pragma once
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace dvs::fuzz {

// Between the parts of a multi-file input (the seed files show where each part goes).
inline constexpr std::string_view kPartSeparator = "\n=====\n";

// A folder of this process's own, made on first use and removed when the process ends normally.
const std::filesystem::path& scratch_dir();

// Writes `bytes` to scratch_dir()/name (folders made as needed) and returns the path.
std::filesystem::path write_scratch(const std::string& name, std::string_view bytes);

// The input as text (bytes as they are).
inline std::string_view as_text(const uint8_t* data, size_t size) { return {reinterpret_cast<const char*>(data), size}; }

// The input cut at kPartSeparator into at most `max_parts` parts (the last one keeps any further separators).
std::vector<std::string_view> split_parts(std::string_view input, size_t max_parts);

}  // namespace dvs::fuzz
