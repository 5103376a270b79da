#include "embed/c_api_guard.hpp"

#include <algorithm>
#include <cstring>
#include <new>

#include "embed/c_api_options.hpp"
#include "vk/check.hpp"

namespace dvs::capi {
namespace {
thread_local std::string last_error;
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
  } catch (const UsageError& e) {
    return fail(DVS_ERROR_INVALID_ARGUMENT, e.what());
  } catch (const Cancelled& e) {
    return fail(DVS_ERROR_CANCELLED, e.what());
  } catch (const vk::DeviceOutOfMemory& e) {
    return fail(DVS_ERROR_OUT_OF_MEMORY, e.what());
  } catch (const vk::DeviceLost& e) {
    return fail(DVS_ERROR_DEVICE, e.what());
  } catch (const Error& e) {
    return fail(error_status, e.what());
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

void copy_out(const std::string& text, char* buffer, size_t size, const char* call, const char* name) {
  if (size == 0) return;
  require(buffer, call, name);
  const size_t n = std::min(text.size(), size - 1);
  std::memcpy(buffer, text.data(), n);
  buffer[n] = '\0';
}

}  // namespace dvs::capi

extern "C" const char* dvs_last_error(void) { return dvs::capi::last_error.c_str(); }
