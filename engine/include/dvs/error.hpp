// The one exception type dvs throws for user-facing problems. Messages name the file/stage, what is
// wrong and, where there is one, what to do about it.
#pragma once
#include <stdexcept>
#include <string>

#include "dvs/api.hpp"

namespace dvs {

class DVS_API Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

// A job stopped on request (Ctrl-C, or a CancelFn returning true); not a failure of the inputs.
class DVS_API Cancelled : public Error {
 public:
  Cancelled() : Error("cancelled") {}
};

}  // namespace dvs
