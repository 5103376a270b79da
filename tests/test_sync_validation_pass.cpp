// The synchronization-validation pass is live: under tests/run_with_sync_validation.sh a test whose recording
// lacks one barrier fails, although its values are right (lavapipe runs commands one after the other). Each
// victim below is a test of this program that passes; it runs again in a child process three times: as it is
// (passes), with one barrier left out by DVS_DEBUG_DROP_BARRIER (vk/dropped_barrier.hpp) and the pass's
// environment (fails, naming the layer's hazard), and with the barrier left out but synchronization validation
// off (passes: by value nothing shows). And a test program ends after its summary under the pass (it hung there:
// support/gpu.cpp). Outside the pass these tests are skipped, as there is nothing to prove.
#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include "support/gpu.hpp"
#include "support/process.hpp"

namespace dvs {
namespace {

struct Victim {
  const char* test;  // a gtest filter of this program naming one test
  const char* drop;  // DVS_DEBUG_DROP_BARRIER
  const char* hazard;  // what the layer must report
};

// ModelsText.T5OtherSizesWithMaskAgainstReference: a T5 encoder forward against a host reference, every
// recording's first hazard barrier left out (a layer's input read before the op writing it is done): a race
// inside one command buffer.
// RecorderSegmentReadsAnEarlierSegmentsResult: the barrier opening the second segment left out: a race between
// two submissions, which only the layer's QueueSubmit check sees.
// ContextSharing.ASceneOutlivesItsContext: a render through the public API, whose dvs::Context gets the layer from
// DVS_VALIDATION=1 and whose messages the test reads nowhere: the process-wide check fails it (it passed, printing
// its hazards, before that check existed).
const Victim kVictims[] = {
    {"ModelsText.T5OtherSizesWithMaskAgainstReference", "1", "SYNC-HAZARD-READ-AFTER-WRITE"},
    {"GpuTest.RecorderSegmentReadsAnEarlierSegmentsResult", "segment:2", "SYNC-HAZARD-READ-AFTER-WRITE"},
    {"ContextSharing.ASceneOutlivesItsContext", "1", "SYNC-HAZARD-READ-AFTER-WRITE"},
};

std::string self() { return "/proc/" + std::to_string(getpid()) + "/exe"; }

TEST(SyncValidationPass, ADroppedBarrierFailsATestThatPassesWithIt) {
  if (!test::sync_validation_enabled())
    GTEST_SKIP() << "synchronization validation is off (VK_LAYER_ENABLES); this test proves the pass "
                    "tests/run_with_sync_validation.sh is live and runs there";
  for (const Victim& v : kVictims) {
    SCOPED_TRACE(std::string(v.test) + " with DVS_DEBUG_DROP_BARRIER=" + v.drop);
    const std::string run = self() + " --gtest_filter=" + v.test;
    const test::CommandResult clean = test::run_command("env -u DVS_DEBUG_DROP_BARRIER " + run);
    EXPECT_EQ(clean.exit_code, 0) << clean.output;
    EXPECT_NE(clean.output.find("[  PASSED  ] 1 test"), std::string::npos) << clean.output;

    const test::CommandResult dropped = test::run_command(std::string("DVS_DEBUG_DROP_BARRIER=") + v.drop + " " + run,
                                                          test::ValidationMessages::expected);
    EXPECT_NE(dropped.exit_code, 0) << dropped.output;
    EXPECT_NE(dropped.output.find(v.hazard), std::string::npos) << dropped.output;
    EXPECT_NE(dropped.output.find("[  FAILED  ] 1 test"), std::string::npos) << dropped.output;

    const test::CommandResult unseen = test::run_command(std::string("env -u VK_LAYER_ENABLES DVS_DEBUG_DROP_BARRIER=") +
                                                         v.drop + " " + run);
    EXPECT_EQ(unseen.exit_code, 0) << unseen.output;
    EXPECT_EQ(unseen.output.find("SYNC-HAZARD"), std::string::npos) << unseen.output;
  }
}

// With the layer's QueueSubmit check on, this program hung after printing its summary whenever the shared test
// context was left to the exit handlers (6 runs of 6 of this victim, which flushes a long recording early and
// finishes in seconds); it is released before main returns now. The limit leaves room for a loaded machine.
TEST(SyncValidationPass, ATestProgramEndsAfterItsSummary) {
  if (!test::sync_validation_enabled())
    GTEST_SKIP() << "synchronization validation is off (VK_LAYER_ENABLES); this test runs under "
                    "tests/run_with_sync_validation.sh";
  const test::CommandResult r =
      test::run_command("timeout 300 " + self() + " --gtest_filter=BoundedSubmission.LongRecordingsAreSubmittedInPartsInOrder");
  EXPECT_NE(r.exit_code, 124) << "still running 300 s later:\n" << r.output;
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("[  PASSED  ] 1 test"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace dvs
