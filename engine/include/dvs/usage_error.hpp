// A command line that cannot be understood (unknown option, missing or malformed value), or a library call's
// argument refused (ErrorKind::invalid_argument). The programs exit with status 2 for it, 1 for failures of the work
// itself, 130 when interrupted.
#pragma once
#include "dvs/error.hpp"
#include "dvs/api.hpp"

namespace dvs {

class DVS_API UsageError : public Error {
 public:
  explicit UsageError(const std::string& what) : Error(what, ErrorKind::invalid_argument) {}
};

}  // namespace dvs
