// The splat renderer's memory figures (geometry/splat_memory.hpp), which the memory plan and the preflights use,
// against what a render really allocates: the device bytes a render_clip holds at its peak equal the footprint's
// total, chunk for chunk, with the limits of the device and under forced lower ones.
#include <gtest/gtest.h>

#include "geometry/splat.hpp"
#include "geometry/splat_memory.hpp"
#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "vk/memory.hpp"

namespace dvs::geometry {
namespace {

class SplatMemory : public test::GpuTest {};

SplatLimits limits_of(const vk::Context& ctx) {
  const vk::DeviceCaps& c = ctx.caps();
  return {c.max_storage_buffer_range, c.max_memory_allocation_size, c.max_workgroup_count[0], c.max_workgroup_count[1], ""};
}

TEST_F(SplatMemory, TheFootprintIsWhatARenderAllocates) {
  const int F = 9, H = 32, W = 48;
  const Intrinsics K = Intrinsics::official_default(W, H);
  HostTensor rgb({F, 3, H, W}, DType::f32), depth({F, H, W}, DType::f32);
  for (int64_t i = 0; i < rgb.numel(); ++i) rgb.as<float>()[i] = float(i % 7) / 7.0f - 0.5f;
  for (int64_t i = 0; i < depth.numel(); ++i) depth.as<float>()[i] = 2.0f + float(i % 5) / 10.0f;
  Trajectory t;
  t.transforms.assign(F, glm::dmat4(1.0));
  // One frame's accumulation is 32 x 48 x 16 B = 24 KiB: no limit, a binding of 3 frames, an allocation of 4.
  for (const char* spec : {"", "binding=72KiB", "alloc=96KiB"}) {
    SCOPED_TRACE(spec);
    test::ScopedLimits scoped(ctx(), *spec ? spec : "binding=1GiB");
    for (const bool points : {false, true}) {
      SplatOptions o;
      o.mode = points ? SplatMode::hard_point : SplatMode::soft_bilinear;
      const SplatFootprint fp = splat_footprint(F, H, W, points, false, limits_of(ctx()), ctx().allocator().alignment());
      ASSERT_TRUE(fp.problem.empty()) << fp.problem;
      // (Under a lower DVS_LIMITS of the whole process, those stay in force and the chunk is theirs.)
      const vk::DeviceCaps& c = ctx().caps();
      if (c.max_storage_buffer_range == (72u << 10) && c.max_memory_allocation_size >= (72u << 10)) {
        EXPECT_EQ(fp.chunk_frames, 3);
      }
      if (c.max_memory_allocation_size == (96u << 10) && c.max_storage_buffer_range >= (96u << 10)) {
        EXPECT_EQ(fp.chunk_frames, 4);
      }
      vk::Allocator& a = ctx().allocator();
      const uint64_t before = a.stats().bytes_in_use;
      a.reset_peak();
      render_clip(ctx(), rgb, depth, t, K, o);
      EXPECT_EQ(a.stats().peak_bytes_in_use - before, fp.total) << (points ? "points" : "soft");
      EXPECT_EQ(a.stats().bytes_in_use, before) << "the render's buffers are freed when it returns";
    }
  }
}

TEST_F(SplatMemory, AFrameOverALimitIsAProblemNamingASizeThatFits) {
  SplatLimits l;
  l.binding = 64 << 10;
  const SplatFootprint over = splat_footprint(9, 96, 128, false, false, l);
  // 96 x 128 x 16 B = 192 KiB; 64 KiB holds 4096 pixels: the same aspect scaled by sqrt(4096 / 12288), to multiples
  // of 8, is 48 x 72.
  EXPECT_NE(over.problem.find("render: one 96x128 frame needs 192.00 KiB"), std::string::npos) << over.problem;
  EXPECT_NE(over.problem.find("at most 4096 pixels, e.g. --size 48x72"), std::string::npos) << over.problem;
  EXPECT_TRUE(splat_footprint(9, 48, 72, false, false, l).problem.empty());
  EXPECT_EQ(splat_footprint(9, 64, 64, false, false, l).chunk_frames, 1);
  l = {};
  l.groups_x = l.groups_y = 64;
  EXPECT_NE(splat_footprint(1, 72, 64, false, false, l).problem.find("over maxComputeWorkGroupCount 64x64"), std::string::npos);
  EXPECT_TRUE(splat_footprint(1, 64, 4096, false, false, l).problem.empty());  // 64 groups of 64 pixels per row
  EXPECT_FALSE(splat_footprint(1, 64, 4097, false, false, l).problem.empty());
}

}  // namespace
}  // namespace dvs::geometry
