// The depth network's input size must be a multiple of 14 (the ViT's patch); Video-Depth-Anything would round any
// other value silently, so `dvs depth --input-size`, and --depth-input-size of render/run/invert/plan, refuse it as
// a usage error (exit 2) and suggest the multiples either side.
#include <gtest/gtest.h>

#include <string>

#include "support/files.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

TEST(CliDepthInputSize, NotAMultipleOf14IsAUsageError) {
  test::TempDir d;
  const std::string dvs = test::program("dvs");
  // At the size the pack's learned positional table takes (another is a usage error of its own).
  const std::string plan_model = " --model " + (test::golden_path() / "model").string() + " --frames 9 --height 64 --width 64";
  const std::string files = " --video " + (d / "v.mp4").string() + " --depth-model " + (d / "m.pth").string();
  const struct {
    std::string command, option;
  } cases[] = {
      {dvs + " depth" + files + " --out " + (d / "o.npz").string() + " --input-size 500", "--input-size"},
      {dvs + " render" + files + " --out " + (d / "o").string() + " --depth-input-size 500", "--depth-input-size"},
      {dvs + " run" + files + " --model " + d.path.string() + " --prompt x --out " + (d / "o").string() +
           " --depth-input-size 500", "--depth-input-size"},
      {dvs + " plan" + plan_model + " --depth-model vits --depth-input-size 500", "--depth-input-size"},
  };
  for (const auto& c : cases) {
    const auto r = test::run_command(c.command);
    EXPECT_EQ(r.exit_code, 2) << c.command << "\n" << r.output;
    EXPECT_NE(r.output.find(c.option + " must be a multiple of 14 (the model's patch size), got 500; e.g. 490 or 504"),
              std::string::npos)
        << c.command << "\n" << r.output;
  }
  // A multiple of 14 passes this check (the plan needs no files).
  const auto ok = test::run_command(dvs + " plan" + plan_model + " --depth-model vits --depth-input-size 504");
  EXPECT_EQ(ok.exit_code, 0) << ok.output;
  EXPECT_EQ(ok.output.find("multiple of 14"), std::string::npos) << ok.output;
}

}  // namespace
}  // namespace dvs
