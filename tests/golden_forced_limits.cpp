// The golden end-to-end chain (PipelineE2e.ChainedFromTheVideo: encode the video, invert, K-RNR, sample,
// decode) a second time under the CI profile's forced limits, against the same goldens at the same
// tolerances, and proof that those limits really take the split paths: every op of kForced below must be in
// ctx().splits() afterwards. Without forced limits the same chain must note no split at all (the fast path).
// Ops whose split the pack's sizes cannot reach under this profile are listed in kNotReached with the
// tests/test_split_*.cpp suite that forces them instead.
#include <gtest/gtest.h>

#include <iostream>
#include <string>

#include "support/pipeline_e2e.hpp"
#include "support/scoped_limits.hpp"

namespace dvs {
namespace {

// The CI profile (tests/run_with_forced_limits.sh sets the same DVS_LIMITS for the whole suite).
constexpr const char* kCiProfile = "binding=64KiB,texels=16384,alloc=4MiB,groups=64";

struct Forced {
  const char* op;
  const char* why;  // which limit of kCiProfile forces it at the pack's sizes
};

// Derived by running the chain under kCiProfile and reading ctx().splits() (printed by the test).
const Forced kForced[] = {
    {"linear", "TODO"},
};

// Ops with a split path that the pack's sizes do not reach under kCiProfile, and where their split is shown.
const Forced kNotReached[] = {
    {"TODO", "TODO"},
};

void print_splits(const std::string& title, const std::map<std::string, uint64_t>& splits) {
  std::cout << title << " (" << splits.size() << " ops):\n";
  for (const auto& [op, n] : splits) std::cout << "  " << op << ": " << n << " calls\n";
}

class ForcedLimits : public e2e::PipelineE2e {};

TEST_F(ForcedLimits, ChainSplitsEveryListedOpAndMatchesTheGoldens) {
  test::ScopedLimits limits(ctx(), kCiProfile);
  ctx().reset_splits();
  chained_from_the_video();
  const auto splits = ctx().splits();
  print_splits("splits under " + std::string(kCiProfile), splits);
  for (const Forced& f : kForced) EXPECT_TRUE(splits.count(f.op)) << f.op << " did not split (" << f.why << ")";
}

TEST_F(ForcedLimits, ChainWithoutForcedLimitsTakesNoSplit) {
  if (ctx().caps().forced_limits.any()) GTEST_SKIP() << "DVS_LIMITS forces limits for the whole process";
  ctx().reset_splits();
  chained_from_the_video();
  print_splits("splits without forced limits", ctx().splits());
  EXPECT_TRUE(ctx().splits().empty()) << "the unsplit fast path noted a split";
}

}  // namespace
}  // namespace dvs
