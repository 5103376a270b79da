// Shared Vulkan context for tests: created once per test process with validation layers on, on the
// device DVS_DEVICE names (CI: lavapipe). GpuTest fails any test during which a validation message
// arrived.
#pragma once
#include <gtest/gtest.h>

#include <string>
#include <vector>

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

// The kernel census's fallbacks so far belong to the running test's purpose: GpuTest::TearDown does not count
// them under DVS_REQUIRE_COOPMAT (the tensor-core pass, tests/run_coopmat_pass.sh).
void forgive_kernel_fallbacks();

// The kernels (census notes) the shared context's GEMM-shaped calls dispatched since the running test started (also
// after forgive_kernel_fallbacks); the precision rule judges a result by them (support/precision_rule.hpp).
std::vector<vk::Context::KernelNote> kernels_run_in_test();

}  // namespace dvs::test
