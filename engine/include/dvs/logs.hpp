// The libraries dvs reads and writes files with (OpenCV and its FFmpeg backend, SentencePiece) print their own
// log lines on stderr; dvs says what went wrong in its own words, so they are silenced unless asked for.
#pragma once

#include "dvs/api.hpp"

namespace dvs {

// Quiet (false, the default) or let the libraries log as they like (true, `--verbose`). Call before the first
// video is opened: FFmpeg's log level is read when OpenCV's backend starts.
DVS_API void set_third_party_logs(bool verbose);

}  // namespace dvs
