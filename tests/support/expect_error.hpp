// Assertions on dvs::Error messages: the reader tests check that every error names the file and the problem.
#pragma once
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "dvs/error.hpp"

namespace dvs::test {

// Expects f() to throw a dvs::Error whose message names `file` and contains `word`.
template <class F>
void expect_error(F&& f, const std::string& file, const std::string& word) {
  try {
    f();
    ADD_FAILURE() << "no error; expected one mentioning '" << word << "'";
  } catch (const dvs::Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(file), std::string::npos) << "message does not name " << file << ": " << msg;
    EXPECT_NE(msg.find(word), std::string::npos) << "message lacks '" << word << "': " << msg;
  }
}

// Expects f() to throw a dvs::Error whose message contains every one of `parts`.
template <class F>
void expect_error(F&& f, const std::vector<std::string>& parts) {
  try {
    f();
    ADD_FAILURE() << "expected a dvs::Error";
  } catch (const dvs::Error& e) {
    for (const auto& p : parts) EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what() << " lacks " << p;
  }
}

// The message of the dvs::Error f() throws, or "" when it throws none.
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const dvs::Error& e) {
    return e.what();
  }
  return "";
}

}  // namespace dvs::test
