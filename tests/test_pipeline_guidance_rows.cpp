// The CFG rows as `dvs run` builds them, checked by value through the whole command. With --guidance 0 the
// guided prediction is the unconditional row alone (u + 0·(c − u) = u exactly), so output.mp4 must not depend on
// --prompt and must depend on --negative-prompt. The golden PipelineE2e tests check guidance_text itself; this
// catches the rows swapped (or one prompt used twice) where run_stages calls it. Runs are byte-reproducible
// (fixed-point splat, fixed encoder heap fill: test_reproducible_run.cpp), so equality is byte equality.
#include <gtest/gtest.h>

#include <string>

#include "support/files.hpp"
#include "support/pipeline_inputs.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

TEST(PipelineGuidanceRows, GuidanceZeroFollowsTheNegativePromptOnly) {
  test::PipelineInputs in;
  const auto run = [&](const std::string& name, const std::string& prompts) {
    const auto out = in.dir / name;
    // Later options win: `prompts` overrides the command's --prompt.
    const auto r = test::run_command(in.command(out, "--no-cache --guidance 0 " + prompts));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return test::read_text(out / "output.mp4");
  };
  // Two texts the pack's tokenizer and T5 tell apart ("" and "a red fox" are its own golden prompts).
  const std::string fox_empty = run("fox_empty", "--prompt 'a red fox' --negative-prompt ''");
  const std::string empty_empty = run("empty_empty", "--prompt '' --negative-prompt ''");
  const std::string fox_fox = run("fox_fox", "--prompt 'a red fox' --negative-prompt 'a red fox'");
  ASSERT_FALSE(fox_empty.empty());
  EXPECT_TRUE(fox_empty == empty_empty) << "with --guidance 0 the prompt (the conditional row) changed the output";
  EXPECT_FALSE(fox_empty == fox_fox) << "with --guidance 0 the negative prompt (the unconditional row) had no effect";
}

}  // namespace
}  // namespace dvs
