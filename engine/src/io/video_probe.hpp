// Why a video file cannot be read, in words a user can act on. FFmpeg (through OpenCV) only says that it could
// not open a file; an empty file, a file cut short and an audio-only file then all look like "unknown container
// or codec". This looks at the bytes itself: the size, and for the ISO base media format (.mp4, .mov, .m4a, the
// common case) the top-level boxes and the tracks' handler types.
#pragma once
#include <filesystem>
#include <string>

namespace dvs {

// What is wrong with `path` as a video and what to do, or "" when nothing specific is found (then the caller's
// own message stands). Examples: "the file is empty (0 bytes): ...; export or copy it again", "holds no video
// stream (its tracks: audio): give the video itself", "the file is truncated: it ends at byte 4096, inside its
// 'mdat' box of 51234 bytes that starts at byte 48, and its index ('moov' box) is missing, ...".
std::string video_file_problem(const std::filesystem::path& path);

// dvs::Error for a video that holds fewer frames than --frames asked for (`announced`: the container's own count, 0
// when it does not say), with the --frames that works.
[[noreturn]] void throw_too_few_frames(const std::string& name, int have, int wanted, int announced);

}  // namespace dvs
