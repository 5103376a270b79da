// What `dvs plan` says about requests it cannot plan as asked: a size the model's learned positional table
// rejects, a depth model that is neither a file nor a released size, a --model that names both the built-in
// configuration and a folder, and the advice when nothing fits a model whose size is fixed. Each is a usage
// error (status 2) naming the fix, never a plan that reads as if it ran.
#include <gtest/gtest.h>

#include <filesystem>

#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

test::CommandResult plan(const std::string& args, const std::string& cwd = "") {
  return test::run_command((cwd.empty() ? std::string() : "cd '" + cwd + "' && ") + "DVS_LIMITS= " + test::program("dvs") +
                           " plan " + args);
}

TEST(PlanMessages, SizeTheLearnedTableRejectsIsAUsageError) {
  const auto r = plan("--model cogvideox-5b-i2v --height 256 --width 384 --budget 80GiB");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("fixes the size to 480x720"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("runs untiled"), std::string::npos) << r.output;
  EXPECT_EQ(plan("--model cogvideox-5b-i2v --height 480 --width 720 --frames 9 --budget 80GiB").exit_code, 0);
}

TEST(PlanMessages, NothingFitsAdviceKeepsTheFixedSize) {
  const auto r = plan("--model cogvideox-5b-i2v --budget 2GiB");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("fewer frames"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("smaller size"), std::string::npos) << "the real model's size is fixed\n" << r.output;
}

TEST(PlanMessages, UnknownDepthModelListsTheReleasedSizes) {
  const auto r = plan("--model cogvideox-5b-i2v --depth-model vitx");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  for (const char* size : {"vitx", "vits", "vitb", "vitl"}) EXPECT_NE(r.output.find(size), std::string::npos) << size << "\n" << r.output;
}

TEST(PlanMessages, FolderNamedLikeTheBuiltInIsNotSilentlyIgnored) {
  test::TempDir d;
  std::filesystem::create_directories(d / "cogvideox-5b-i2v");
  const auto r = plan("--model cogvideox-5b-i2v", d.path.string());
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("both the built-in configuration and the folder"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("./cogvideox-5b-i2v"), std::string::npos) << r.output;
  // Spelled as a path it is the folder (here without configs: an error naming them).
  const auto folder = plan("--model ./cogvideox-5b-i2v", d.path.string());
  EXPECT_NE(folder.exit_code, 0);
  EXPECT_NE(folder.output.find("config.json"), std::string::npos) << folder.output;
  // Elsewhere the name is the built-in.
  EXPECT_EQ(plan("--model cogvideox-5b-i2v").exit_code, 0);
}

}  // namespace
}  // namespace dvs
