// dvs/dvs.h: dvs_set_log_callback, the library's warnings (dvs/logs.hpp) to a C function, with the C structs' names
// for the options they mention. A C program that sets no callback gets the default line on stderr, in those names
// too (installed by the first call that takes options, unless the application installed a handler of its own).
#include "dvs/logs.hpp"
#include "embed/c_api_guard.hpp"
#include "embed/c_api_options.hpp"
#include "io/library_log.hpp"

namespace dvs::capi {
namespace {

void c_default(LogLevel, const std::string& message) { write_warning_to_stderr(c_option_names(message)); }

}  // namespace

void use_c_names_in_default_log() { install_log_handler_if_none(c_default); }

}  // namespace dvs::capi

extern "C" dvs_status dvs_set_log_callback(dvs_log_fn fn, void* user) {
  using namespace dvs::capi;
  return guarded(DVS_ERROR_INTERNAL, [&] {
    if (!fn) return dvs::set_log_handler(c_default);
    dvs::set_log_handler([fn, user](dvs::LogLevel, const std::string& message) {
      fn(DVS_LOG_WARNING, c_option_names(message).c_str(), user);
    });
  });
}
