// A full disk (and other failed writes) named as such. Writers that cannot see the error code (OpenCV's video
// writer drops FFmpeg's write errors) check the free space of the folder they wrote into.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>

namespace dvs {

// Below this many free bytes a folder counts as full: a write that failed (or was cut short) there failed
// for lack of space (FFmpeg and stdio buffer 32–64 KiB, so a full disk can keep that much unused).
constexpr uint64_t kNearlyFullBytes = 64 * 1024;

// "no space left on device (FOLDER has N bytes free)" when the file system holding `folder` is (nearly)
// full, else "".
std::string no_space_note(const std::filesystem::path& folder);

// Why a write of a file in `folder` failed with `err` (errno) and what to do: ENOSPC names the full disk, EIO
// the device's I/O error, anything else its strerror text.
std::string write_error_note(int err, const std::filesystem::path& folder);

}  // namespace dvs
