#include "embed/c_api_guard.hpp"

#include <cstring>
#include <new>

#include "vk/check.hpp"

namespace dvs::capi {
namespace {
thread_local std::string last_error;
}  // namespace

dvs_status fail(dvs_status status, const std::string& message) {
  try {
    last_error = message;
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

void copy_out(const std::string& text, char* buffer, size_t size, const char* call, const char* name) {
  if (size == 0) return;
  require(buffer, call, name);
  const size_t n = std::min(text.size(), size - 1);
  std::memcpy(buffer, text.data(), n);
  buffer[n] = '\0';
}

}  // namespace dvs::capi

extern "C" const char* dvs_last_error(void) { return dvs::capi::last_error.c_str(); }
