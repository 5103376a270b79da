// Trajectory files as users get them wrong: a binary file named as one (its bytes must not reach the terminal),
// stray control bytes, and the authors' format with lines of different lengths (allowed, and said: a warning).
#include <gtest/gtest.h>

#include <string>

#include "dvs/error.hpp"
#include "geometry/trajectory.hpp"
#include "support/expect_error.hpp"
#include "support/files.hpp"

namespace dvs::geometry {
namespace {

bool has_raw_bytes(const std::string& s) {
  for (char c : s)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) return true;
  return false;
}

TEST(TrajectoryInput, BinaryFileIsNamedNotTextWithoutItsBytes) {
  test::TempDir d;
  const std::string npy_start("\x93NUMPY\x01\x00v\x00{'descr': '<f4'}\x00\xff\xfe", 28);
  for (const char* name : {"path.txt", "path.json"}) {
    test::write_text(d / name, npy_start);
    const std::string msg = test::error_of([&] { load_trajectory((d / name).string(), 9, 1.0); });
    EXPECT_NE(msg.find(std::string(name) + ": not a text file (byte \\x93 at offset 0; it starts \"\\x93NUMPY\\x01\\x00v"),
              std::string::npos)
        << msg;
    EXPECT_NE(msg.find("three lines of numbers"), std::string::npos) << msg;
    EXPECT_FALSE(has_raw_bytes(msg)) << msg;
  }
}

TEST(TrajectoryInput, ControlBytesInAWordArePrintedEscaped) {
  test::TempDir d;
  test::write_text(d / "t.txt", "0 1\x1b[2J 2\n0 0\n0 0\n");  // an escape sequence that would clear the screen
  const std::string msg = test::error_of([&] { load_trajectory((d / "t.txt").string(), 9, 1.0); });
  EXPECT_NE(msg.find("t.txt:1: '1\\x1b[2J' is not a finite number"), std::string::npos) << msg;
  EXPECT_FALSE(has_raw_bytes(msg)) << msg;
  // A UTF-8 byte-order mark (some editors write one) is not part of the first number.
  test::write_text(d / "bom.txt", "\xEF\xBB\xBF" "0 5\n0 0\n0 0\n");
  EXPECT_EQ(load_trajectory((d / "bom.txt").string(), 3, 1.0).frames(), 3);
}

// The authors' loop1.txt has 13, 9 and 8 values on its three lines: each is interpolated over the clip on its own.
TEST(TrajectoryInput, LinesOfDifferentLengthsAreAllowedDescribedAndWarned) {
  test::TempDir d;
  test::write_text(d / "loop.txt", "0 2 10 15 12 6 0 -2 -5 -12 -8 -3 0\n0 -3 -10 -20 -30 -25 -17 -10 0\n"
                                   "0 -0.02 -0.09 -0.16 -0.25 -0.2 -0.09 0\n");
  const Trajectory t = load_trajectory((d / "loop.txt").string(), 49, 1.0);
  EXPECT_EQ(t.frames(), 49);
  EXPECT_NE(t.description.find("(knots: theta 13, phi 9, r 8; lines of different lengths are each spread over the "
                               "whole clip on their own"),
            std::string::npos)
      << t.description;
  ASSERT_EQ(t.warnings.size(), 1u) << "lines of different lengths must be said";
  EXPECT_EQ(t.warnings[0], (d / "loop.txt").string() + ": its lines hold different numbers of values: line 1 (theta) 13 "
                           "values, line 2 (phi) 9 values, line 3 (r) 8 values. dvs spreads each line over the whole clip "
                           "on its own (its first value at the first frame, its last at the last frame), as the authors' "
                           "loader does, so the i-th values of different lines do not fall on the same frame; give every "
                           "line the same number of values to keep them together");
  test::write_text(d / "even.txt", "0 5 10\n0 1 2\n0 0 0\n");
  const Trajectory e = load_trajectory((d / "even.txt").string(), 9, 1.0);
  EXPECT_NE(e.description.find("(3 knots per line)"), std::string::npos);
  EXPECT_TRUE(e.warnings.empty());
}

}  // namespace
}  // namespace dvs::geometry
