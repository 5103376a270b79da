// A GPU test run twice: with texel-buffer inputs (the default where views allow) and forced onto the
// storage-buffer shaders, so both variants of every op are checked. Instantiate with
// DVS_TEXEL_PATHS(Prefix, Fixture): the cases are named .../texel and .../storage.
#pragma once
#include <gtest/gtest.h>

#include "support/gpu.hpp"
#include "tensor/ops_elementwise.hpp"

namespace dvs::test {

class TexelPathsTest : public GpuTest, public ::testing::WithParamInterface<bool> {
 protected:
  void SetUp() override {
    GpuTest::SetUp();
    ops::use_texel_inputs(GetParam());
  }
  void TearDown() override {
    ops::use_texel_inputs(true);
    GpuTest::TearDown();
  }
};

}  // namespace dvs::test

#define DVS_TEXEL_PATHS(prefix, fixture)                    \
  INSTANTIATE_TEST_SUITE_P(prefix, fixture, ::testing::Bool(), \
                           [](const ::testing::TestParamInfo<bool>& i) { return i.param ? "texel" : "storage"; })
