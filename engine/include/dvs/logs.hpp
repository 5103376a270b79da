// The library's own messages and the libraries under it.
//
// dvs's own warnings (a camera path that shows nothing in some frames, a cache that cannot be written, a prompt
// longer than the model reads, a cached entry found damaged, a video written as an .npy frame array, a pipeline
// cache that cannot be saved) go to one log handler: by default a line "dvs: warning: ..." on stderr; an
// application installs its own to show them in its UI or its log. They name options as dvs/option_names.hpp says.
//
// The libraries dvs reads and writes files with (OpenCV and its FFmpeg backend, SentencePiece) print their own
// log lines on stderr; dvs says what went wrong in its own words, so they are silenced unless asked for.
#pragma once
#include <functional>
#include <string>

#include "dvs/api.hpp"

namespace dvs {

enum class LogLevel { warning };

// Receives each message (without the "dvs: warning: " prefix the default handler writes), on the thread that
// has it: a job's messages come from the job's thread. It must not throw (an exception is dropped).
using LogHandler = std::function<void(LogLevel level, const std::string& message)>;

// Process-wide; an empty handler restores the default (stderr). Safe to call from any thread at any time: a
// message in flight goes to the handler installed when it was sent.
DVS_API void set_log_handler(LogHandler handler);

// Quiet (false, the default) or let the libraries log as they like (true, `--verbose`). Call before the first
// video is opened: FFmpeg's log level is read when OpenCV's backend starts.
DVS_API void set_third_party_logs(bool verbose);

}  // namespace dvs
