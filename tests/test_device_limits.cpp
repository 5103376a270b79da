// DVS_LIMITS: parsing (units, subsets, every malformed form is an error naming the item), lowering the caps
// every op plans against (never raising them), and `dvs info`'s report marking the forced ones.
#include <gtest/gtest.h>

#include "dvs/usage_error.hpp"
#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "vk/device_info.hpp"
#include "vk/device_limits.hpp"

namespace dvs {
namespace {

TEST(DeviceLimits, ParsesUnitsAndSubsets) {
  auto o = vk::parse_limit_overrides("binding=64KiB,texels=16384,alloc=1MiB");
  ASSERT_TRUE(o.binding && o.texels && o.alloc);
  EXPECT_EQ(*o.binding, 64u * 1024);
  EXPECT_EQ(*o.texels, 16384u);
  EXPECT_EQ(*o.alloc, 1u << 20);
  EXPECT_FALSE(o.groups);
  auto g = vk::parse_limit_overrides(" groups = 4096 , alloc=2GiB ");
  EXPECT_EQ(*g.groups, 4096u);
  EXPECT_EQ(*g.alloc, 2ull << 30);
  EXPECT_FALSE(g.binding);
  EXPECT_FALSE(vk::parse_limit_overrides("").any());
}

TEST(DeviceLimits, MalformedValuesAreErrorsNamingTheItem) {
  for (const char* bad : {"binding", "binding=", "binding=64KB", "binding=-1", "binding=0", "bindings=64KiB",
                          "binding=64KiB,binding=1MiB", "binding=64KiB,,alloc=1MiB", "texels=12", "binding=1000",
                          "groups=8", "alloc=1KiB", "binding=1.5MiB"}) {
    try {
      vk::parse_limit_overrides(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const UsageError& e) {
      EXPECT_NE(std::string(e.what()).find("DVS_LIMITS"), std::string::npos) << e.what();
    }
  }
}

TEST(DeviceLimits, LowerOnlyAndRemembered) {
  vk::DeviceCaps c;
  c.max_storage_buffer_range = 128ull << 20;
  c.max_texel_buffer_elements = 1ull << 27;
  c.max_memory_allocation_size = 2ull << 30;
  c.max_workgroup_count[0] = c.max_workgroup_count[1] = c.max_workgroup_count[2] = 65535;
  vk::apply_limit_overrides(c, vk::parse_limit_overrides("binding=64KiB,alloc=4GiB,groups=100"));
  EXPECT_EQ(c.max_storage_buffer_range, 64u * 1024);
  EXPECT_TRUE(c.forced_limits.binding);
  EXPECT_EQ(c.max_memory_allocation_size, 2ull << 30) << "an override above the device's must not raise it";
  EXPECT_FALSE(c.forced_limits.alloc);
  EXPECT_EQ(c.max_texel_buffer_elements, 1ull << 27);
  EXPECT_FALSE(c.forced_limits.texels);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(c.max_workgroup_count[i], 100u);
  EXPECT_EQ(c.device_limits.binding, 128ull << 20);
  EXPECT_EQ(c.device_limits.groups[1], 65535u);
  const std::string report = vk::describe_device(c);
  EXPECT_NE(report.find("maxStorageBufferRange:      64.0 KiB * [128.0 MiB]"), std::string::npos) << report;
  EXPECT_NE(report.find("maxComputeWorkGroupCount:   100 x 100 x 100 * [65535 x 65535 x 65535]"), std::string::npos)
      << report;
  EXPECT_NE(report.find("maxMemoryAllocationSize:    2.0 GiB\n"), std::string::npos) << report;
}

using test::GpuTest;

TEST_F(GpuTest, ScopedLimitsLowerAndRestore) {
  const uint64_t binding = ctx().caps().max_storage_buffer_range, texels = ctx().caps().max_texel_buffer_elements;
  {
    test::ScopedLimits forced(ctx(), "binding=4KiB,groups=64");
    EXPECT_EQ(ctx().caps().max_storage_buffer_range, std::min<uint64_t>(binding, 4096));
    EXPECT_EQ(ctx().caps().max_workgroup_count[2], 64u);
    EXPECT_EQ(ctx().caps().max_texel_buffer_elements, texels);
  }
  EXPECT_EQ(ctx().caps().max_storage_buffer_range, binding);
  EXPECT_EQ(ctx().caps().max_texel_buffer_elements, texels);
}

}  // namespace
}  // namespace dvs
