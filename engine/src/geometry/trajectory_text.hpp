// Trajectory files are text (the authors' three lines of numbers, or JSON). A binary file given by mistake (a
// video, a .npy, a .glb renamed) must be named as not text, and no error may print its raw bytes: they can
// corrupt the terminal. These two helpers read such a file and quote pieces of it safely.
#pragma once
#include <filesystem>
#include <string>
#include <string_view>

namespace dvs::geometry {

// The whole file as text. Throws dvs::Error naming the file when it cannot be opened, or when it holds a NUL
// byte or is not UTF-8 ("not a text file: byte 0x93 at offset 0 ..."), saying what a trajectory file is.
std::string read_trajectory_text(const std::filesystem::path& path);

// `text` for an error message: control and non-ASCII bytes as \xNN, cut to `max_chars` with "..." after.
std::string printable_excerpt(std::string_view text, size_t max_chars = 40);

}  // namespace dvs::geometry
