// `dvs encode-prompt` as `dvs run` treats its prompt: a prompt longer than the model reads is warned about, and an
// output that cannot be written is named by the user's own path, before the text encoder runs.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

std::string encode_prompt_command(const std::string& prompt, const std::filesystem::path& out) {
  return test::program("dvs") + " encode-prompt --model " + (test::golden_path() / "model").string() + " --prompt '" +
         prompt + "' --out " + out.string();
}

// The pack's model reads 8 tokens (max_text_seq_length, </s> included).
TEST(EncodePromptChecks, LongPromptIsWarnedAboutAsInRun) {
  test::TempDir dir;
  const auto r = test::run_command(encode_prompt_command("a red fox jumps over the lazy brown dog in the snow", dir / "long.npy"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("dvs encode-prompt: warning: --prompt is "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" tokens but this model reads 8 (max_text_seq_length"), std::string::npos) << r.output;
  const auto short_prompt = test::run_command(encode_prompt_command("a red fox", dir / "short.npy"));
  ASSERT_EQ(short_prompt.exit_code, 0) << short_prompt.output;
  EXPECT_EQ(short_prompt.output.find("warning"), std::string::npos) << short_prompt.output;
}

TEST(EncodePromptChecks, UnwritableOutputNamesTheUsersPath) {
  test::TempDir dir;
  const auto out = dir / "no_such_folder" / "x.npy";
  const auto r = test::run_command(encode_prompt_command("a red fox", out));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(out.string() + ": cannot create the file: the folder " + (dir / "no_such_folder").string() +
                          " does not exist"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find(".tmp-"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace dvs
