// The library's own warnings (dvs/logs.hpp): every part of the core sends them here instead of writing to stderr,
// so that an application's log handler (C++ set_log_handler, C dvs_set_log_callback) receives them.
#pragma once
#include <string>

#include "dvs/logs.hpp"

namespace dvs {

// Sends `message` (no "warning: " prefix) to the installed handler, or to stderr as "dvs: warning: <message>".
// Never throws.
void log_warning(const std::string& message) noexcept;

// The default handler's line: "dvs: warning: <message>" on stderr.
void write_warning_to_stderr(const std::string& message) noexcept;

// Installs `handler` unless the application has installed one (the C API's default, which names the C structs'
// fields, for a C program that never set a callback). Returns whether it did.
bool install_log_handler_if_none(LogHandler handler);

}  // namespace dvs
