#include "vk/validation_log.hpp"

#include <mutex>
#include <utility>

namespace dvs::vk::validation_log {
namespace {

struct Log {
  std::mutex mutex;
  std::vector<std::pair<const void*, std::string>> messages;  // source, text
};

Log& log() {
  static Log* l = new Log;  // never destroyed: a context may report while the program's statics go
  return *l;
}

}  // namespace

void add(const void* source, const std::string& message) {
  std::lock_guard<std::mutex> lock(log().mutex);
  log().messages.emplace_back(source, message);
}

void clear(const void* source) {
  std::lock_guard<std::mutex> lock(log().mutex);
  std::erase_if(log().messages, [&](const auto& m) { return m.first == source; });
}

void forget_source(const void* source) {
  std::lock_guard<std::mutex> lock(log().mutex);
  for (auto& m : log().messages)
    if (m.first == source) m.first = nullptr;  // a later context at the same address must not clear them
}

void mark() {
  std::lock_guard<std::mutex> lock(log().mutex);
  log().messages.clear();
}

std::vector<std::string> unread() {
  std::lock_guard<std::mutex> lock(log().mutex);
  std::vector<std::string> texts;
  for (const auto& m : log().messages) texts.push_back(m.second);
  return texts;
}

}  // namespace dvs::vk::validation_log
