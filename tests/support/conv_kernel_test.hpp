// A fixture for tests of the tensor-core convolution kernel's variants: it runs the kernel itself where the device
// has a cooperative-matrix shape (the tensor-core pass, tests/run_coopmat_pass.sh), else its fp32 twin
// (nn/conv_coopmat_twin), which shares the loads; and runs a list of conv paths (vae_conv_paths.hpp), keeping each
// output's bits.
#pragma once
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "support/vae_conv_paths.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv.hpp"

namespace dvs::test {

class ConvKernelTest : public GpuTest {
 protected:
  void SetUp() override {
    GpuTest::SetUp();
    twin_ = !ops::device_tuning(ctx().caps()).coopmat.defined();
    ops::ConvRegisterBlock blk;
    blk.coopmat_twin = twin_;
    ops::set_conv_register_block(blk);
  }
  void TearDown() override {
    ops::set_conv_register_block({});
    GpuTest::TearDown();
  }
  // The kernel's pipeline name on this device.
  std::string gemm_name() const { return twin_ ? "nn/conv_coopmat_twin" : "nn/conv_coopmat"; }
  // y of each path under `limits` (nullptr: none), one vector of bits each; names_ the paths' names, in order.
  std::vector<std::vector<uint32_t>> run_paths(const std::vector<VaeConvPath>& paths, const char* limits) {
    vk::Context& c = ctx();
    std::vector<std::vector<uint32_t>> out;
    names_.clear();
    for (const VaeConvPath& path : paths) {
      names_.push_back(path.name);
      const Tensor o = Tensor::empty(c, path.out, DType::f32);
      {
        std::unique_ptr<ScopedLimits> scope;
        if (limits) scope = std::make_unique<ScopedLimits>(c, limits);
        ops::run_now(c, [&](vk::Recorder& rec) { path.call(rec, o); });
      }
      const HostTensor h = o.download(c);
      out.emplace_back(size_t(h.numel()));
      std::memcpy(out.back().data(), h.data.data(), out.back().size() * 4);
    }
    return out;
  }
  // The paths `run` (a callable returning run_paths' result) gives under tuning override `a` against under `b` (each
  // replaces the override in force): every path's output the same bits; failures name the path and `where`.
  template <class Run>
  void expect_same_bits(const std::string& a, const std::string& b, Run run, const std::string& where) {
    std::vector<std::vector<uint32_t>> ya, yb;
    {
      ops::ScopedTuningOverride t(a);
      ya = run();
    }
    {
      ops::ScopedTuningOverride t(b);
      yb = run();
    }
    ASSERT_EQ(ya.size(), yb.size());
    for (size_t i = 0; i < ya.size(); ++i) {
      size_t differ = 0;
      for (size_t k = 0; k < ya[i].size(); ++k) differ += ya[i][k] != yb[i][k];
      EXPECT_EQ(differ, 0u) << names_[i] << ", " << where << ": elements that differ between " << a << " and " << b;
    }
  }
  bool twin_ = false;
  std::vector<std::string> names_;
};

}  // namespace dvs::test
