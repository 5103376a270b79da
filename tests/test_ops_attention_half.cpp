// Attention with fp16 operands: k and v in the tensor cores' operand type, the output in the next GEMM's (the
// transformer's to_out input where the GEMMs run on tensor cores). Each flash kernel the device can run (tiled; the
// tensor-core kernel's fp32 twin; the KHR tensor-core kernel and its VK_NV_cooperative_matrix2 variant where the
// device has them) runs each call with k and v holding fp16 values three ways: f32 k, v into an f32 out, into an f16
// out, and f16 k, v into an f32 out. The f16 out's bits must be exactly the f32 out rounded to nearest even (the
// host's reference rounding), the f16 k, v must give the f32 ones' bits; f16 operands in views at a byte offset that
// is a multiple of 8 but not of 16, with a padded row stride and a column offset, nothing written outside the heads.
// Then the calls that must refuse f16 operands: the texel kernel (an f16 q there too), a head_dim that runs on padded
// copies, a misaligned out, k and v of two dtypes. (f16 q: test_ops_attention_heads.cpp.)
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "support/attention_reference.hpp"
#include "support/expect_error.hpp"
#include "support/gpu.hpp"
#include "support/kernel_calls.hpp"
#include "tensor/coopmat_layout.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_attention.hpp"
#include "vk/pipeline.hpp"

namespace dvs::test {
namespace {

using ops::AttentionOperand;
using ops::AttentionOptions;
using ops::AttentionShape;

constexpr uint16_t kUntouchedHalf = 0x5a5a;  // what the f16 out holds outside the heads, before and after
constexpr int64_t kColumn = 4, kExtra = 8;    // out's column offset and extra columns per row

class AttentionOps : public GpuTest {
 protected:
  // An out [B, Lq, H·D + kExtra] of `dt` at byte offset `lead` into its buffer, every element `fill` (bits).
  Tensor make_out(const AttentionShape& s, DType dt, VkDeviceSize lead, uint32_t fill) {
    const int64_t n = s.batch * s.q_len * (s.heads * s.head_dim + kExtra);
    const VkDeviceSize elem = dtype_size(dt), bytes = VkDeviceSize(n) * elem;
    HostTensor h({int64_t(lead / elem) + n}, dt);
    for (int64_t i = 0; i < h.numel(); ++i) {
      if (dt == DType::f32) h.as<uint32_t>()[i] = fill;
      else h.as<uint16_t>()[i] = uint16_t(fill);
    }
    const Tensor whole = Tensor::upload(ctx(), h);
    keep_.push_back(whole);
    return Tensor::on(whole.buffer().sub(lead, bytes), {s.batch, s.q_len, s.heads * s.head_dim + kExtra}, dt);
  }
  // Whether a pipeline of `shader` with its O_F16 constant (spec entry `index`) set was created.
  bool half_pipeline(const std::string& shader, size_t index) {
    bool found = false;
    ctx().pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name == shader && pl.spec.size() > index && pl.spec[index] == 1) found = true;
    });
    return found;
  }
  // k or v of `in` with its values rounded to fp16, as f32 (`dt` f32) or as f16 at byte offset 8 into its buffer.
  AttentionOperand rounded(const attention_ref::HostOperand& h, const AttentionShape& s, DType dt) {
    HostTensor t({int64_t(h.data.size()) + 4}, dt);
    for (size_t i = 0; i < h.data.size(); ++i) {
      const uint16_t bits = f32_to_f16(h.data[i]);
      if (dt == DType::f32) t.as<float>()[i] = f16_to_f32(bits);
      else t.as<uint16_t>()[i + 4] = bits;
    }
    const Tensor whole = Tensor::upload(ctx(), t);
    keep_.push_back(whole);
    const VkDeviceSize lead = dt == DType::f16 ? 8 : 0, bytes = VkDeviceSize(h.data.size()) * dtype_size(dt);
    const int64_t rows = int64_t(h.data.size()) / h.stride;
    return {Tensor::on(whole.buffer().sub(lead, bytes), {s.batch, rows / s.batch, h.stride}, dt), h.offset, h.stride};
  }
  // Runs the call with k and v holding fp16 values, three times: f32 k, v into an f32 out; the same into an f16 out;
  // f16 k, v into an f32 out. Expects the f16 out's bits to be the first out's values rounded to nearest even, and
  // the third out to be the first's bits.
  void same_values_rounded(const AttentionShape& s, const std::string& shader, size_t o_f16_index, uint32_t seed) {
    SCOPED_TRACE(shader + " D" + std::to_string(s.head_dim));
    const attention_ref::Operands in = attention_ref::random_operands(ctx(), s, false, 4, seed);
    const AttentionOperand k32 = rounded(in.hk, s, DType::f32), v32 = rounded(in.hv, s, DType::f32);
    const AttentionOperand k16 = rounded(in.hk, s, DType::f16), v16 = rounded(in.hv, s, DType::f16);
    const int64_t W = s.heads * s.head_dim, os = W + kExtra;
    const Tensor out32 = make_out(s, DType::f32, 0, 0x7fc00000u);  // NaN where not written
    const Tensor out16 = make_out(s, DType::f16, 8, kUntouchedHalf);
    const Tensor out_kv16 = make_out(s, DType::f32, 0, 0x7fc00000u);
    const AttentionOptions opt{.scale = 1.0f / std::sqrt(float(s.head_dim))};
    if (!ops::attention_takes_f16(ctx().caps(), s, in.q, k32, v32, {out32, kColumn, os}, opt)) {
      ASSERT_TRUE(ctx().caps().forced_limits.any()) << "a flash kernel's call must take f16 operands";
      GTEST_SKIP() << "the limits in force send this call to the texel kernel";
    }
    const uint64_t before = kernel_calls(ctx(), shader);
    ops::run_now(ctx(), [&](vk::Recorder& rec) {
      ops::attention(rec, s, in.q, k32, v32, {out32, kColumn, os}, opt);
      ops::attention(rec, s, in.q, k32, v32, {out16, kColumn, os}, opt);
      ops::attention(rec, s, in.q, k16, v16, {out_kv16, kColumn, os}, opt);
    });
    EXPECT_EQ(kernel_calls(ctx(), shader), before + 3) << "not run by " << shader;
    EXPECT_TRUE(half_pipeline(shader, o_f16_index)) << "no " << shader << " pipeline with O_F16 set";
    EXPECT_TRUE(half_pipeline(shader, o_f16_index + 1)) << "no " << shader << " pipeline with KV_F16 set";
    const std::vector<float> f = out32.download(ctx()).to_f32();
    const HostTensor h = out16.download(ctx()), g = out_kv16.download(ctx());
    const uint16_t* bits = h.as<uint16_t>();
    size_t wrong = 0, touched = 0, unwritten = 0;
    for (int64_t row = 0; row < s.batch * s.q_len; ++row)
      for (int64_t col = 0; col < os; ++col) {
        const size_t i = size_t(row * os + col);
        if (col < kColumn || col >= kColumn + W) {
          touched += bits[i] != kUntouchedHalf;
        } else {
          unwritten += std::isnan(f[i]);
          wrong += bits[i] != f32_to_f16(f[i]);
        }
      }
    EXPECT_EQ(unwritten, 0u) << "the f32 call left elements unwritten";
    EXPECT_EQ(wrong, 0u) << "f16 elements that are not the f32 values rounded to nearest even";
    EXPECT_EQ(touched, 0u) << "f16 elements written outside the heads";
    EXPECT_EQ(std::memcmp(g.data.data(), out32.download(ctx()).data.data(), g.data.size()), 0)
        << "f16 k and v give another result than f32 ones holding the same values";
  }
  std::vector<Tensor> keep_;
};

TEST_F(AttentionOps, HalfOperandsGiveTheFloatResultOnEveryFlashKernel) {
  uint32_t seed = 900;
  {
    ops::ScopedTuningOverride tiled("attention=tiled");
    for (int64_t d : {64, 12})  // 12: three groups of 4 a head
      same_values_rounded({2, 3, d, 37, 45}, "nn/attention_flash", 3, seed++);
  }
  if (ctx().caps().float16_arithmetic) {
    // 4 subgroups, the KHR kernel's (the twin's) layout: the table's coopmat2 rows (16 subgroups where the device has
    // VK_NV_cooperative_matrix2) hold more than the twin's shared arrays fit in.
    ops::ScopedTuningOverride twin("attention=tiled,attention_coopmat_twin=on,attention_block_k=32,attention_coopmat_subgroups=4");
    same_values_rounded({2, 3, 32, 37, 45}, "nn/attention_flash_coopmat_twin", 8, seed++);
  }
  if (!ops::device_tuning(ctx().caps()).coopmat.defined()) {
    std::cout << "[ SKIPPED  ] the tensor-core kernels: no cooperative-matrix shape on this device\n";
    return;
  }
  {
    ops::ScopedTuningOverride khr("attention=coopmat,attention_coopmat2=off");
    same_values_rounded({2, 3, 32, 37, 45}, "nn/attention_flash_coopmat", 8, seed++);
  }
  const ops::DeviceTuning& t = ops::device_tuning(ctx().caps());
  const ops::CoopmatAttention a = ops::attention_coopmat_layout(t);
  if (ctx().caps().cooperative_matrix2_row_ops && a.frag.n == a.frag.k) {
    ops::ScopedTuningOverride nv("attention=coopmat,attention_coopmat2=on");
    same_values_rounded({2, 3, 32, 37, 45}, "nn/attention_flash_coopmat2", 8, seed++);
  }
}

TEST_F(AttentionOps, HalfOperandsRefusedWhereNoFlashKernelTakesThem) {
  const AttentionShape s{1, 2, 16, 5, 7};
  const attention_ref::Operands in = attention_ref::random_operands(ctx(), s, false, 0, 950);
  const Tensor out32 = make_out(s, DType::f32, 0, 0);
  const Tensor out16 = make_out(s, DType::f16, 0, 0);
  const int64_t os = s.heads * s.head_dim + kExtra;
  auto run = [&](const AttentionShape& sh, const attention_ref::Operands& ops_in, const AttentionOperand& out,
                 const AttentionOptions& opt) {
    ops::run_now(ctx(), [&](vk::Recorder& rec) { ops::attention(rec, sh, ops_in.q, ops_in.k, ops_in.v, out, opt); });
  };
  {
    ops::ScopedTuningOverride texel("attention=texel");
    EXPECT_FALSE(ops::attention_takes_f16(ctx().caps(), s, in.q, in.k, in.v, {out32, 0, os}));
    expect_error([&] { run(s, in, {out16, 0, os}, {}); }, {"f16 or head-major operand", "texel kernel"});
  }
  ops::ScopedTuningOverride tiled("attention=tiled");
  if (!ctx().caps().forced_limits.any()) {
    EXPECT_TRUE(ops::attention_takes_f16(ctx().caps(), s, in.q, in.k, in.v, {out32, 0, os}));
  }
  // A key mask (T5) runs on the texel kernel.
  const Tensor mask = Tensor::upload(ctx(), HostTensor::from_f32({1, 7}, std::vector<float>(7, 1.0f)));
  const AttentionOptions masked{.key_mask = &mask};
  EXPECT_FALSE(ops::attention_takes_f16(ctx().caps(), s, in.q, in.k, in.v, {out32, 0, os}, masked));
  expect_error([&] { run(s, in, {out16, 0, os}, masked); }, {"f16 or head-major operand", "texel kernel"});
  // head_dim 6: padded copies, copied back in f32.
  const AttentionShape odd{1, 2, 6, 5, 7};
  const attention_ref::Operands in6 = attention_ref::random_operands(ctx(), odd, false, 0, 951);
  const Tensor out6 = make_out(odd, DType::f16, 0, 0);
  EXPECT_FALSE(ops::attention_takes_f16(ctx().caps(), odd, in6.q, in6.k, in6.v, {make_out(odd, DType::f32, 0, 0)}));
  expect_error([&] { run(odd, in6, {out6, 0, 2 * 6 + kExtra}, {}); }, {"f16 or head-major operand", "multiple of 4", "head_dim 6"});
  // An f16 out whose start is not a whole group of 4 halves; an f16 q on the texel kernel.
  const Tensor shifted = make_out(s, DType::f16, 4, 0);
  expect_error([&] { run(s, in, {shifted, 0, os}, {}); }, {"out", "multiple of 8"});
  attention_ref::Operands half_q = in;
  half_q.q.t = make_out(s, DType::f16, 0, 0);
  half_q.q.row_stride = os;
  {
    ops::ScopedTuningOverride texel_q("attention=texel");
    expect_error([&] { run(s, half_q, {out32, 0, os}, {}); }, {"f16 or head-major operand", "texel kernel"});
  }
  // f16 k with f32 v; f16 k and v on the texel kernel.
  attention_ref::Operands half_kv = in;
  const AttentionShape kv_rows{s.batch, s.heads, s.head_dim, s.kv_len, s.kv_len};  // make_out's rows: kv_len
  half_kv.k.t = make_out(kv_rows, DType::f16, 0, 0);
  half_kv.k.row_stride = os;
  expect_error([&] { run(s, half_kv, {out32, 0, os}, {}); }, {"one dtype for both"});
  half_kv.v.t = make_out(kv_rows, DType::f16, 0, 0);
  half_kv.v.row_stride = os;
  ops::ScopedTuningOverride texel("attention=texel");
  expect_error([&] { run(s, half_kv, {out32, 0, os}, {}); }, {"f16 or head-major operand", "texel kernel"});
}

}  // namespace
}  // namespace dvs::test
