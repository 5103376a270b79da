// `dvs-weights make-tiny` refuses what could never be used or would destroy a model: a --sample size no run can
// take (odd latent sides, a frame count that is not 4k+1), and an --out folder that already holds files (unless
// --force, as merge-lora refuses such a folder).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

namespace fs = std::filesystem;
const std::string kTool = test::program("dvs-weights");

TEST(MakeTinyChecks, SampleSizesThatCanNeverRunAreUsageErrors) {
  test::TempDir d;
  const struct {
    const char* sample;
    const char* says;
  } cases[] = {
      {"7x8x9", "latent height and width must be even"},  {"8x8x10", "frames must be 4k+1"},
      {"0x8x9", "latent height and width must be even"},  {"-2x8x9", "latent height and width must be even"},
      {"8x8x0", "frames must be 4k+1"},                     {"8x8x9x", "must be LATENT_HxLATENT_WxFRAMES"},
  };
  for (const auto& c : cases) {
    const auto r = test::run_command(kTool + " make-tiny --layers 1 --t5-layers 1 --sample " + c.sample + " --out " +
                                     (d / "m").string());
    EXPECT_EQ(r.exit_code, 2) << c.sample << ": " << r.output;
    EXPECT_NE(r.output.find(c.says), std::string::npos) << c.sample << ": " << r.output;
    EXPECT_NE(r.output.find(std::string("got '") + c.sample + "'"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(d / "m")) << c.sample;
  }
}

TEST(MakeTinyChecks, ExistingModelIsNotOverwrittenWithoutForce) {
  test::TempDir d;
  const std::string base = kTool + " make-tiny --layers 1 --t5-layers 1 --out " + (d / "m").string();
  ASSERT_EQ(test::run_command(base + " --seed 1").exit_code, 0);
  const fs::path weights = d / "m" / "transformer" / "diffusion_pytorch_model.safetensors";
  const std::string first = test::read_text(weights);
  const auto again = test::run_command(base + " --seed 2");
  EXPECT_EQ(again.exit_code, 1) << again.output;
  EXPECT_NE(again.output.find((d / "m").string() + ": already exists and is not an empty folder (it holds a model); "
                              "choose another --out, or give --force"),
            std::string::npos)
      << again.output;
  EXPECT_EQ(test::read_text(weights), first);
  const auto forced = test::run_command(base + " --seed 2 --force");
  EXPECT_EQ(forced.exit_code, 0) << forced.output;
  EXPECT_NE(test::read_text(weights), first);
  // An empty folder (made beforehand, e.g. by mktemp -d) is fine without --force.
  fs::create_directories(d / "empty");
  EXPECT_EQ(test::run_command(kTool + " make-tiny --layers 1 --t5-layers 1 --out " + (d / "empty").string()).exit_code, 0);
}

}  // namespace
}  // namespace dvs
