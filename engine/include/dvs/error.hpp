// The one exception type dvs throws for user-facing problems. Messages name the file/stage, what is
// wrong and, where there is one, what to do about it; kind() tells the broad cause apart without reading the text
// (each kind is one status code of the C API, dvs/dvs.h). Nothing but a dvs::Error leaves a dvs call.
#pragma once
#include <stdexcept>
#include <string>

#include "dvs/api.hpp"

namespace dvs {

enum class ErrorKind {
  input,             // the work failed on its inputs: a file missing, unreadable or malformed, a model that does not
                     // fit the device (DVS_ERROR_FILE)
  invalid_argument,  // a call's argument or option refused before any work: a null or mis-shaped view, a bad pose or
                     // preset, a ticket never submitted, a context in use by a job (DVS_ERROR_INVALID_ARGUMENT)
  device,            // no usable Vulkan device, or one without what dvs needs (DVS_ERROR_DEVICE)
  device_lost,       // the device was lost (VK_ERROR_DEVICE_LOST): nothing on it survives (DVS_ERROR_DEVICE_LOST)
  out_of_memory,     // host or device memory ran out (DVS_ERROR_OUT_OF_MEMORY)
  cancelled,         // stopped on request: dvs::Cancelled (DVS_ERROR_CANCELLED)
  internal,          // a failure dvs does not expect: a bug, please report the message (DVS_ERROR_INTERNAL)
};

class DVS_API Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what, ErrorKind kind = ErrorKind::input) : std::runtime_error(what), kind_(kind) {}
  ErrorKind kind() const noexcept { return kind_; }

 private:
  ErrorKind kind_;
};

// A job stopped on request (Ctrl-C, or a CancelFn returning true); not a failure of the inputs.
class DVS_API Cancelled : public Error {
 public:
  Cancelled() : Error("cancelled", ErrorKind::cancelled) {}
};

}  // namespace dvs
