// set_log_handler (dvs/logs.hpp) and log_warning (io/library_log.hpp). The handler is copied out under the lock
// and called outside it, so a handler may log again or install another without a deadlock.
#include "io/library_log.hpp"

#include <cstdio>
#include <memory>
#include <mutex>

#include "dvs/logs.hpp"

namespace dvs {
namespace {

std::mutex& handler_mutex() {
  static std::mutex m;
  return m;
}

std::shared_ptr<const LogHandler>& installed() {
  static std::shared_ptr<const LogHandler> h;
  return h;
}

}  // namespace

void set_log_handler(LogHandler handler) {
  auto next = handler ? std::make_shared<const LogHandler>(std::move(handler)) : nullptr;
  const std::lock_guard<std::mutex> lock(handler_mutex());
  installed() = std::move(next);
}

bool install_log_handler_if_none(LogHandler handler) {
  auto next = std::make_shared<const LogHandler>(std::move(handler));
  const std::lock_guard<std::mutex> lock(handler_mutex());
  if (installed()) return false;
  installed() = std::move(next);
  return true;
}

void log_warning(const std::string& message) noexcept {
  std::shared_ptr<const LogHandler> h;
  {
    const std::lock_guard<std::mutex> lock(handler_mutex());
    h = installed();
  }
  try {
    if (h) return (*h)(LogLevel::warning, message);
  } catch (...) {
    return;  // the handler's own failure: nothing sensible to do with it here
  }
  write_warning_to_stderr(message);
}

void write_warning_to_stderr(const std::string& message) noexcept {
  std::fprintf(stderr, "dvs: warning: %s\n", message.c_str());
  std::fflush(stderr);
}

}  // namespace dvs
