// The boundary of the public C++ API: only a dvs::Error leaves a dvs call. A dvs::Error passes as it is; host memory
// running out (std::bad_alloc, std::length_error of a size no allocation can hold) becomes ErrorKind::out_of_memory
// and any other exception ErrorKind::internal, each naming the call.
#pragma once
#include <new>
#include <stdexcept>
#include <string>

#include "dvs/error.hpp"

namespace dvs::embed {

template <class Body>
auto public_call(const char* call, Body&& body) -> decltype(body()) {
  try {
    return body();
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw Error(std::string(call) + ": out of host memory (the sizes given need more than this machine can allocate)",
                ErrorKind::out_of_memory);
  } catch (const std::length_error& e) {
    throw Error(std::string(call) + ": out of host memory (a size beyond any allocation: " + e.what() + ")",
                ErrorKind::out_of_memory);
  } catch (const std::exception& e) {
    throw Error(std::string(call) + ": internal error: " + e.what(), ErrorKind::internal);
  } catch (...) {
    throw Error(std::string(call) + ": internal error: an exception that is not a std::exception", ErrorKind::internal);
  }
}

}  // namespace dvs::embed
