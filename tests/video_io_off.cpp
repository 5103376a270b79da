// Built only with DVS_VIDEO_IO=OFF (the GPU bundle): one skipped test per test file left out of such a build
// because it reads or writes videos or depth images (tests/CMakeLists.txt lists them), so the run says what it
// did not cover instead of silently testing less.
#include <gtest/gtest.h>

#include <sstream>
#include <string>

TEST(VideoIoOff, TestFilesNotBuilt) {
  std::stringstream files(DVS_VIDEO_TEST_FILES);
  std::string f, all;
  while (std::getline(files, f, ',')) all += " tests/" + f + ".cpp";
  GTEST_SKIP() << "built without video I/O (DVS_VIDEO_IO=OFF): not built:" << all;
}
