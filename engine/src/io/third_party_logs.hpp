// The libraries dvs reads and writes files with (OpenCV and its FFmpeg backend, SentencePiece) print their
// own log lines on stderr ("[mov,mp4 @ 0x…] moov atom not found", "LOG(INFO) Running command: …"). dvs says
// what went wrong in its own words, so those lines are silenced unless the user asks for them (--verbose).
#pragma once

namespace dvs {

// Quiet (false, the default) or let the libraries log as they like (true). Call before the first video is
// opened: FFmpeg's log level is read by OpenCV when its backend starts.
void set_third_party_logs(bool verbose);
bool third_party_logs_verbose();
// Whether set_third_party_logs was called; remember_third_party_logs records a choice without passing it on to the
// video component (the component's own copy of this state, in libdvs_video, is set through it).
bool third_party_logs_chosen();
void remember_third_party_logs(bool verbose);

// While alive, and while the libraries are quiet, file descriptor 2 points at /dev/null: for the few
// library calls that print with fprintf(stderr) whatever their log level (OpenCV's codec-tag fallback, the
// SentencePiece trainer's command line). Keep the scope to the one call.
class QuietStderr {
 public:
  QuietStderr();
  ~QuietStderr();
  QuietStderr(const QuietStderr&) = delete;
  QuietStderr& operator=(const QuietStderr&) = delete;

 private:
  int saved_ = -1;
};

}  // namespace dvs
