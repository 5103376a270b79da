// The C API's boundary (dvs/dvs.h): every call runs its body through guarded(), which turns any C++ exception into
// a dvs_status and keeps the message for dvs_last_error() on this thread, so no exception crosses into C.
#pragma once
#include <cstddef>
#include <string>

#include "dvs/dvs.h"
#include "dvs/pipeline.hpp"
#include "dvs/usage_error.hpp"

namespace dvs::capi {

// Records `message` as this thread's last error and returns `status`.
dvs_status fail(dvs_status status, const std::string& message);

// The status of an exception in flight (call inside a catch): UsageError = invalid argument, Cancelled,
// out of host or device memory, a lost device, other dvs::Error = `error_status` (what a failure of this call
// most likely is: the device for a context, the inputs elsewhere), anything else internal.
dvs_status status_of_current_exception(dvs_status error_status);

template <class Body>
dvs_status guarded(dvs_status error_status, Body&& body) noexcept {
  try {
    body();
    return DVS_OK;
  } catch (...) {
    return status_of_current_exception(error_status);
  }
}

// Throws UsageError "<call>: <name> is NULL" for a missing pointer argument.
void require(const void* pointer, const char* call, const char* name);

// A C progress callback (nonzero = cancel) as the C++ call's progress and cancellation.
struct CProgress {
  dvs_progress_fn progress = nullptr;
  void* user = nullptr;
  bool cancel = false;
  ProgressFn fn() {
    if (!progress) return {};
    return [this](const std::string& stage, int step, int total, const std::string& note) {
      if (progress(stage.c_str(), step, total, note.c_str(), user) != 0) cancel = true;
    };
  }
  CancelFn cancelled() {
    return [this] { return cancel; };
  }
};

// Copies `text` into buffer (size bytes, NUL-terminated, truncated to fit). buffer may be NULL only with size 0.
void copy_out(const std::string& text, char* buffer, size_t size, const char* call, const char* name);

}  // namespace dvs::capi
