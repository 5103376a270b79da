// Shared Vulkan context for tests: created once per test process with validation layers on, on the
// device DVS_DEVICE names (CI: lavapipe). GpuTest fails any test during which a validation message
// arrived.
#pragma once
#include <gtest/gtest.h>

#include <string>

#include "vk/context.hpp"

namespace dvs::test {

vk::Context& gpu();

class GpuTest : public ::testing::Test {
 protected:
  void SetUp() override;
  void TearDown() override;
  vk::Context& ctx() { return gpu(); }
};

std::string golden_dir();  // DVS_GOLDEN_DIR or tests/golden/A

// Whether the validation layer checks synchronization in this process: VK_LAYER_ENABLES names it
// (tests/run_with_sync_validation.sh sets it; the layer reads it when an instance is made).
bool sync_validation_enabled();

}  // namespace dvs::test
