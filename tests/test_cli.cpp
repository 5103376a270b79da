// The command-line programs as a user runs them: exit codes and messages.
#include <gtest/gtest.h>

#include <string>

#include "support/process.hpp"

namespace {

using dvs::test::run_command;
const std::string kDvs = dvs::test::program("dvs");

TEST(Cli, InfoListsDevices) {
  auto r = run_command(kDvs + " info");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Device 0:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("maxStorageBufferRange"), std::string::npos);
  EXPECT_NE(r.output.find("maxMemoryAllocationSize"), std::string::npos);
  EXPECT_NE(r.output.find("maxComputeSharedMemorySize"), std::string::npos);
  EXPECT_NE(r.output.find("selected"), std::string::npos);
}

TEST(Cli, InfoWithUnknownDeviceFails) {
  auto r = run_command(kDvs + " info --device no-such-gpu");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("no-such-gpu"), std::string::npos) << r.output;
  auto env = run_command("DVS_DEVICE=no-such-gpu-env " + kDvs + " info");
  EXPECT_NE(env.exit_code, 0);
  EXPECT_NE(env.output.find("no-such-gpu-env"), std::string::npos) << env.output;
}

TEST(Cli, UnknownCommandAndHelp) {
  EXPECT_EQ(run_command(kDvs + " --help").exit_code, 0);
  auto r = run_command(kDvs + " frobnicate");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("unknown command"), std::string::npos);
  EXPECT_NE(run_command(kDvs + " info --bogus").exit_code, 0);
}

}  // namespace
