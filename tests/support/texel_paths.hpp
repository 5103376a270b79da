// A GPU test run twice: forced onto texel-buffer inputs (where views allow) and onto the storage-buffer
// shaders (what the "gpu" tuning entry runs), so both variants of every op are checked. Instantiate with
// DVS_TEXEL_PATHS(Prefix, Fixture): the cases are named .../texel and .../storage.
#pragma once
#include <gtest/gtest.h>

#include <optional>

#include "support/gpu.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_elementwise.hpp"

namespace dvs::test {

class TexelPathsTest : public GpuTest, public ::testing::WithParamInterface<bool> {
 protected:
  void SetUp() override {
    GpuTest::SetUp();
    tuning_.emplace(GetParam() ? "eltwise_texel_inputs=on" : "eltwise_texel_inputs=off");
  }
  void TearDown() override {
    tuning_.reset();
    GpuTest::TearDown();
  }

 private:
  std::optional<ops::ScopedTuningOverride> tuning_;
};

}  // namespace dvs::test

#define DVS_TEXEL_PATHS(prefix, fixture)                    \
  INSTANTIATE_TEST_SUITE_P(prefix, fixture, ::testing::Bool(), \
                           [](const ::testing::TestParamInfo<bool>& i) { return i.param ? "texel" : "storage"; })
