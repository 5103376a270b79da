// The C API's boundary (embed/c_api_guard.hpp): statuses, the last error per thread, the string calls' rule.
#include "embed/c_api_guard.hpp"

#include <algorithm>
#include <cstring>
#include <new>

#include "embed/c_api_options.hpp"

namespace dvs::capi {
namespace {
thread_local std::string last_error;

// A dvs::Error's kind as its C status (dvs/error.hpp names each kind's code).
dvs_status status_of(ErrorKind kind, dvs_status input_status) {
  switch (kind) {
    case ErrorKind::input: return input_status;
    case ErrorKind::invalid_argument: return DVS_ERROR_INVALID_ARGUMENT;
    case ErrorKind::device: return DVS_ERROR_DEVICE;
    case ErrorKind::device_lost: return DVS_ERROR_DEVICE_LOST;
    case ErrorKind::out_of_memory: return DVS_ERROR_OUT_OF_MEMORY;
    case ErrorKind::cancelled: return DVS_ERROR_CANCELLED;
    case ErrorKind::internal: return DVS_ERROR_INTERNAL;
  }
  return DVS_ERROR_INTERNAL;
}
}  // namespace

dvs_status fail(dvs_status status, const std::string& message) {
  try {
    last_error = c_option_names(message);  // the C structs' field names, not the C++ ones
  } catch (...) {
    // No memory even for the message: the status still says what happened.
  }
  return status;
}

dvs_status status_of_current_exception(dvs_status error_status) {
  try {
    throw;
  } catch (const Error& e) {
    return fail(status_of(e.kind(), error_status), e.what());
  } catch (const std::bad_alloc&) {
    return fail(DVS_ERROR_OUT_OF_MEMORY, "out of host memory");
  } catch (const std::exception& e) {
    return fail(DVS_ERROR_INTERNAL, std::string("internal error: ") + e.what());
  } catch (...) {
    return fail(DVS_ERROR_INTERNAL, "internal error: an exception that is not a std::exception");
  }
}

void require(const void* pointer, const char* call, const char* name) {
  if (!pointer) throw UsageError(std::string(call) + ": " + name + " is NULL");
}

void check_size(int32_t value, const char* call, const char* name) {
  if (value < 1) throw UsageError(std::string(call) + ": " + name + " must be >= 1, got " + std::to_string(value));
}

void check_clip_size(int32_t count, int32_t height, int32_t width, const char* call) {
  check_size(count, call, "count");
  check_size(height, call, "height");
  check_size(width, call, "width");
}

ElementType element_type(dvs_element_type t, const char* call, const char* name) {
  if (t == DVS_F32) return ElementType::f32;
  if (t == DVS_U8) return ElementType::u8;
  throw UsageError(std::string(call) + ": " + name + " must be DVS_F32 or DVS_U8, got " + std::to_string(int(t)));
}

Pose pose_of(const double pose[16]) {
  Pose p;
  std::copy(pose, pose + 16, p.m.begin());
  return p;
}

std::vector<int64_t> scene_image_shape(ElementType type, int64_t height, int64_t width) {
  return type == ElementType::u8 ? std::vector<int64_t>{height, width, 4} : std::vector<int64_t>{3, height, width};
}

void copy_out(const std::string& text, char* buffer, size_t size, size_t* needed, const char* call, const char* name) {
  if (needed) *needed = text.size() + 1;
  if (size == 0 && !buffer) return;  // a size query
  require(buffer, call, name);
  if (size == 0)
    throw UsageError(std::string(call) + ": " + name + " is given with size 0; the text needs " +
                     std::to_string(text.size() + 1) + " bytes (NUL included)");
  const size_t n = std::min(text.size(), size - 1);
  std::memcpy(buffer, text.data(), n);
  buffer[n] = '\0';
  if (n < text.size())
    throw UsageError(std::string(call) + ": " + name + " holds " + std::to_string(size) + " bytes but the text needs " +
                     std::to_string(text.size() + 1) + " (NUL included); it holds the text cut short: pass a buffer of "
                     "that size (the call's `needed` argument gives it)");
}

}  // namespace dvs::capi

extern "C" const char* dvs_last_error(void) { return dvs::capi::last_error.c_str(); }
