// The recorder's barrier tracking as a table: binding kind (storage buffer, uniform texel buffer, storage texel
// buffer, copy, fill) × hazard between two commands (read after write, write after read, write after write,
// none: read after read) × the two ranges of one buffer overlapping or disjoint (adjacent: the second starts
// where the first ends). Each case records exactly one barrier where the two commands conflict (a hazard on
// overlapping ranges) and none otherwise, and computes what a host model of the two commands computes.
// Under tests/run_with_sync_validation.sh the Khronos layer judges each case as well: a case recorded without a
// barrier must raise no hazard (the layer agrees the ranges are independent), and each case that needs one,
// recorded again with that barrier left out (DVS_DEBUG_DROP_BARRIER=1), must raise the hazard it names. Debian
// 12's layer (1.3.239) never reports a write after write between two shader writes of the same kind (a heuristic,
// SupressedBoundDescriptorWAW, takes them for increment updates), so for those two cases (storage buffer and
// storage texel buffer, WAW) the barrier count is the only check.
#include <gtest/gtest.h>

#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include "dvs/usage_error.hpp"
#include "support/gpu.hpp"
#include "vk/dropped_barrier.hpp"
#include "vk/memory.hpp"
#include "vk/pipeline.hpp"
#include "vk/recorder.hpp"
#include "vk/transfer.hpp"

namespace dvs {
namespace {

using test::GpuTest;

enum class Kind { storage, uniform_texel, storage_texel, copy, fill };
enum class Hazard { raw, war, waw, none };

const char* name(Kind k) {
  switch (k) {
    case Kind::storage: return "storage buffer";
    case Kind::uniform_texel: return "uniform texel buffer";
    case Kind::storage_texel: return "storage texel buffer";
    case Kind::copy: return "copy";
    case Kind::fill: return "fill";
  }
  return "?";
}

const char* name(Hazard h) {
  switch (h) {
    case Hazard::raw: return "read after write";
    case Hazard::war: return "write after read";
    case Hazard::waw: return "write after write";
    case Hazard::none: return "read after read";
  }
  return "?";
}

// The layer's message ID for the hazard a left-out barrier causes.
const char* layer_hazard_id(Hazard h) {
  switch (h) {
    case Hazard::raw: return "SYNC-HAZARD-READ-AFTER-WRITE";
    case Hazard::war: return "SYNC-HAZARD-WRITE-AFTER-READ";
    case Hazard::waw: return "SYNC-HAZARD-WRITE-AFTER-WRITE";
    case Hazard::none: return "";
  }
  return "";
}

// One command's access to the shared buffer: it reads the shared range into its own buffer, or writes its own
// buffer (a fill: zeros) into the shared range.
struct Access {
  Kind kind;
  bool writes;
};

// The two commands of a case. The kind under test makes both accesses where it can; a uniform texel buffer
// cannot be written and a fill cannot read, so the other side is a storage buffer there, and the cases the kind
// cannot make at all (a uniform texel buffer writing after a write, a fill reading after a read) do not exist.
std::optional<std::pair<Access, Access>> commands(Kind k, Hazard h) {
  const bool reads = k != Kind::fill, writes = k != Kind::uniform_texel;
  const Access read{reads ? k : Kind::storage, false}, write{writes ? k : Kind::storage, true};
  switch (h) {
    case Hazard::raw: return std::pair{write, read};
    case Hazard::war: return std::pair{read, write};
    case Hazard::waw: return writes ? std::optional{std::pair{write, write}} : std::nullopt;
    case Hazard::none: return reads ? std::optional{std::pair{read, read}} : std::nullopt;
  }
  return std::nullopt;
}

constexpr uint32_t kRange = 256;  // floats per range (1 KiB: any device's binding and texel-view alignment)
constexpr uint32_t kShared = 4 * kRange;

// Records one access: `shared` is the shared buffer's range, `own` the command's own buffer.
void record(vk::Context& ctx, vk::Recorder& rec, const Access& a, const vk::BufferView& shared, const vk::BufferView& own) {
  const vk::BufferView& src = a.writes ? own : shared;
  const vk::BufferView& dst = a.writes ? shared : own;
  const uint32_t n = kRange, groups = (kRange + 63) / 64;
  switch (a.kind) {
    case Kind::storage:
      rec.dispatch(ctx.pipelines().get("test/access_probe"), {src, dst}, &n, 4, groups);
      break;
    case Kind::uniform_texel:
      rec.dispatch(ctx.pipelines().get("test/access_probe_utexel"), {vk::Binding(src, VK_FORMAT_R32_SFLOAT), dst}, &n,
                   4, groups);
      break;
    case Kind::storage_texel:
      rec.dispatch(ctx.pipelines().get("test/access_probe_stexel"),
                   {vk::Binding(src, VK_FORMAT_R32_SFLOAT), vk::Binding(dst, VK_FORMAT_R32_SFLOAT)}, &n, 4, groups);
      break;
    case Kind::copy:
      rec.copy(src, dst, kRange * 4);
      break;
    case Kind::fill:
      rec.fill_zero(dst);
      break;
  }
}

// The same access on host arrays: the probe shaders add 1, a copy copies, a fill writes zeros.
void model(const Access& a, std::vector<float>& shared, uint32_t first, std::vector<float>& own) {
  for (uint32_t i = 0; i < kRange; ++i) {
    float& dst = a.writes ? shared[first + i] : own[i];
    const float src = a.writes ? own[i] : shared[first + i];
    dst = a.kind == Kind::fill ? 0.0f : a.kind == Kind::copy ? src : src + 1.0f;
  }
}

std::vector<float> download(vk::Context& ctx, const vk::Buffer& b, size_t n) {
  std::vector<float> v(n);
  ctx.transfer().download(b.view(), v.data(), n * 4);
  return v;
}

TEST_F(GpuTest, RecorderBarriersByBindingKindHazardAndRange) {
  const bool layer_judges = test::sync_validation_enabled();
  if (!layer_judges)
    std::cout << "[   NOTE   ] synchronization validation is off: the layer does not judge the cases here "
                 "(tests/run_with_sync_validation.sh turns it on)\n";
  int cases = 0, with_barrier = 0;
  for (Kind kind : {Kind::storage, Kind::uniform_texel, Kind::storage_texel, Kind::copy, Kind::fill})
    for (Hazard hazard : {Hazard::raw, Hazard::war, Hazard::waw, Hazard::none})
      for (bool overlap : {true, false}) {
        const auto cmds = commands(kind, hazard);
        if (!cmds) continue;
        const std::string what = std::string(name(kind)) + ", " + name(hazard) + ", ranges " +
                                 (overlap ? "overlapping" : "disjoint");
        SCOPED_TRACE(what);
        ++cases;
        // Shared floats [0, 256) for the first command, [128, 384) or [256, 512) for the second.
        const uint32_t second_first = overlap ? kRange / 2 : kRange;
        std::vector<float> shared(kShared), own1(kRange), own2(kRange);
        for (uint32_t i = 0; i < kShared; ++i) shared[i] = float(i);
        for (uint32_t i = 0; i < kRange; ++i) own1[i] = 1000.0f + float(i), own2[i] = 2000.0f + float(i);
        vk::Buffer b_shared = ctx().allocator().allocate(kShared * 4), b_own1 = ctx().allocator().allocate(kRange * 4),
                   b_own2 = ctx().allocator().allocate(kRange * 4);
        ctx().transfer().upload(b_shared.view(), shared.data(), kShared * 4);
        ctx().transfer().upload(b_own1.view(), own1.data(), kRange * 4);
        ctx().transfer().upload(b_own2.view(), own2.data(), kRange * 4);
        const vk::BufferView range1 = b_shared.view().sub(0, kRange * 4),
                             range2 = b_shared.view().sub(second_first * 4, kRange * 4);

        vk::Recorder rec(ctx());
        rec.begin();
        record(ctx(), rec, cmds->first, range1, b_own1.view());
        record(ctx(), rec, cmds->second, range2, b_own2.view());
        const uint32_t needed = hazard != Hazard::none && overlap ? 1 : 0;
        EXPECT_EQ(rec.barrier_count(), needed);
        with_barrier += int(rec.barrier_count());
        rec.submit();
        model(cmds->first, shared, 0, own1);
        model(cmds->second, shared, second_first, own2);
        EXPECT_EQ(download(ctx(), b_shared, kShared), shared);
        EXPECT_EQ(download(ctx(), b_own1, kRange), own1);
        EXPECT_EQ(download(ctx(), b_own2, kRange), own2);
        auto messages = ctx().validation_messages();
        EXPECT_TRUE(messages.empty()) << messages.size() << " validation message(s), first: " << messages[0];
        ctx().clear_validation_messages();

        const bool layer_blind = hazard == Hazard::waw && (kind == Kind::storage || kind == Kind::storage_texel);
        if (!layer_judges || needed == 0 || layer_blind) continue;
        // The same two commands without their barrier: the layer must name the hazard (at recording time).
        setenv("DVS_DEBUG_DROP_BARRIER", "1", 1);
        vk::Recorder dropped(ctx());
        dropped.begin();
        record(ctx(), dropped, cmds->first, range1, b_own1.view());
        record(ctx(), dropped, cmds->second, range2, b_own2.view());
        dropped.end();
        unsetenv("DVS_DEBUG_DROP_BARRIER");
        EXPECT_EQ(dropped.barrier_count(), 0u);
        messages = ctx().validation_messages();
        ctx().clear_validation_messages();
        ASSERT_FALSE(messages.empty()) << "no hazard reported without the barrier";
        EXPECT_NE(messages[0].find(layer_hazard_id(hazard)), std::string::npos) << messages[0];
      }
  EXPECT_EQ(cases, 36);  // 5 kinds × 4 hazards × 2, less the 4 a kind cannot make
  EXPECT_EQ(with_barrier, 14);
}

// A later segment reads what an earlier one wrote: the barrier opening each segment orders them (the victim of
// SyncValidationPass.*: without that barrier, DVS_DEBUG_DROP_BARRIER=segment:2, the layer's QueueSubmit check
// reports the race; by value nothing shows on lavapipe).
TEST_F(GpuTest, RecorderSegmentReadsAnEarlierSegmentsResult) {
  std::vector<float> x(kRange);
  for (uint32_t i = 0; i < kRange; ++i) x[i] = float(i);
  vk::Buffer a = ctx().allocator().allocate(kRange * 4), b = ctx().allocator().allocate(kRange * 4),
             c = ctx().allocator().allocate(kRange * 4);
  ctx().transfer().upload(a.view(), x.data(), kRange * 4);
  vk::Recorder rec(ctx());
  rec.begin();
  record(ctx(), rec, {Kind::storage, false}, a.view(), b.view());  // b = a + 1
  rec.boundary("first");
  record(ctx(), rec, {Kind::storage, false}, b.view(), c.view());  // c = b + 1
  rec.end();
  EXPECT_EQ(rec.segment_count(), 2u);
  EXPECT_EQ(rec.barrier_count(), 0u);  // ordered by the segment's opening barrier, not by a hazard barrier
  rec.submit();
  const std::vector<float> y = download(ctx(), c, kRange);
  for (uint32_t i = 0; i < kRange; ++i) ASSERT_EQ(y[i], float(i) + 2.0f) << i;
}

TEST(DroppedBarrierSwitch, ReadsNAndSegmentNAndRefusesAnythingElse) {
  using K = vk::DroppedBarrier::Kind;
  EXPECT_EQ(vk::parse_dropped_barrier("").kind, K::none);
  const vk::DroppedBarrier third = vk::parse_dropped_barrier("3");
  EXPECT_TRUE(third.kind == K::hazard && third.index == 3 && third.drops_hazard(3) && !third.drops_hazard(2));
  EXPECT_FALSE(third.drops_segment(3));
  const vk::DroppedBarrier second_segment = vk::parse_dropped_barrier("segment:2");
  EXPECT_TRUE(second_segment.drops_segment(2) && !second_segment.drops_segment(1) && !second_segment.drops_hazard(2));
  for (const char* bad : {"0", "segment:0", "segment:", "x", "-1", "1.5", " 2", "segment:x", "seg:2", "9999999999"}) {
    try {
      vk::parse_dropped_barrier(bad);
      ADD_FAILURE() << "'" << bad << "' was accepted";
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("DVS_DEBUG_DROP_BARRIER='" + std::string(bad) + "'"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("segment:N"), std::string::npos) << e.what();
    }
  }
}

// Exactly the N-th barrier goes; the tracker goes on as if it were there, so the barriers after it stay.
TEST_F(GpuTest, DroppedBarrierLeavesOutExactlyTheNthOne) {
  vk::Buffer a = ctx().allocator().allocate(kRange * 4), b = ctx().allocator().allocate(kRange * 4),
             c = ctx().allocator().allocate(kRange * 4), d = ctx().allocator().allocate(kRange * 4);
  auto chain = [&](vk::Recorder& rec) {  // b = a, c = b, d = c: a read after write before the second and third
    rec.begin();
    rec.copy(a.view(), b.view(), kRange * 4);
    rec.copy(b.view(), c.view(), kRange * 4);
    rec.boundary("after two");
    rec.copy(c.view(), d.view(), kRange * 4);  // ordered by the second segment's opening barrier
    rec.copy(d.view(), a.view(), kRange * 4);
    rec.end();
  };
  vk::Recorder rec(ctx());
  chain(rec);
  EXPECT_EQ(rec.barrier_count(), 2u);
  setenv("DVS_DEBUG_DROP_BARRIER", "1", 1);
  chain(rec);
  EXPECT_EQ(rec.barrier_count(), 1u);
  setenv("DVS_DEBUG_DROP_BARRIER", "segment:2", 1);
  chain(rec);
  EXPECT_EQ(rec.barrier_count(), 2u);  // a segment's opening barrier is not counted
  EXPECT_EQ(rec.segment_count(), 2u);
  unsetenv("DVS_DEBUG_DROP_BARRIER");
  const auto messages = ctx().validation_messages();
  ctx().clear_validation_messages();
  if (test::sync_validation_enabled()) {  // the left-out hazard barrier: one read after write, seen as recorded
    // (nothing is submitted, so no QueueSubmit check runs)
    ASSERT_EQ(messages.size(), 1u) << (messages.empty() ? "" : messages[0]);
    EXPECT_NE(messages[0].find("SYNC-HAZARD-READ-AFTER-WRITE"), std::string::npos) << messages[0];
  }
}

}  // namespace
}  // namespace dvs
