// The one exception type dvs throws for user-facing problems. Messages name the file/stage, what is
// wrong and, where there is one, what to do about it.
#pragma once
#include <stdexcept>
#include <string>

namespace dvs {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

}  // namespace dvs
