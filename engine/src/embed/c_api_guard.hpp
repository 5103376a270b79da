// The C API's boundary (dvs/dvs.h): every call runs its body through guarded(), which turns any C++ exception into
// a dvs_status and keeps the message for dvs_last_error() on this thread, so no exception crosses into C.
#pragma once
#include <cstddef>
#include <string>

#include "dvs/dvs.h"
#include "dvs/pipeline.hpp"
#include "dvs/scene.hpp"
#include "dvs/views.hpp"
#include "dvs/usage_error.hpp"

namespace dvs::capi {

// Records `message` as this thread's last error and returns `status`.
dvs_status fail(dvs_status status, const std::string& message);

// The status of an exception in flight (call inside a catch): a dvs::Error's kind (dvs/error.hpp) as its status code,
// except that ErrorKind::input is `error_status` (what a failure of this call's work most likely is: DVS_ERROR_FILE
// for the inputs almost everywhere); host memory running out = DVS_ERROR_OUT_OF_MEMORY; anything else internal.
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

// Throws UsageError "<call>: <name> must be >= 1, got N" for a count or size below 1.
void check_size(int32_t value, const char* call, const char* name);

// check_size of a clip's count, height and width.
void check_clip_size(int32_t count, int32_t height, int32_t width, const char* call);

// DVS_F32 / DVS_U8 as dvs::ElementType; anything else a UsageError naming the argument.
ElementType element_type(dvs_element_type t, const char* call, const char* name);

// 16 row-major doubles as a Pose.
Pose pose_of(const double pose[16]);

// The shape of a scene's rendered image in `type`: u8 [H,W,4] RGBA or f32 [3,H,W].
std::vector<int64_t> scene_image_shape(ElementType type, int64_t height, int64_t width);

// The string calls' rule (dvs/dvs.h): *needed (when not NULL) = the bytes `text` needs, NUL included; `text` copied
// into buffer when it fits; a buffer too small gets the text truncated (NUL-terminated) and a UsageError naming both
// sizes. buffer may be NULL only with size 0 (a size query).
void copy_out(const std::string& text, char* buffer, size_t size, size_t* needed, const char* call, const char* name);

}  // namespace dvs::capi
