// Attention (shaders/nn/attention.comp) against a plain double-precision softmax(q·kᵀ·scale + bias + mask)·v.
// Tolerance: |gpu − ref| ≤ 2e-5 + 2e-5·max|v| per element (fp32 accumulation over ≤ a few hundred keys,
// lavapipe's exp2 approximation; the output is a convex combination of v rows).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <vector>

#include "support/attention_reference.hpp"
#include "support/gpu.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_attention.hpp"

namespace dvs::test {
namespace {

using ops::AttentionOperand;
using ops::AttentionOptions;
using ops::AttentionShape;

using attention_ref::HostOperand;
using attention_ref::random_values;
using attention_ref::reference;

struct Case {
  int64_t batch, heads, head_dim, q_len, kv_len;
  float scale = 1.0f;
  bool bias = false, mask = false;
  bool fused = false;         // q, k, v as slices of one [B, L, 3·H·D] tensor (needs q_len == kv_len)
  int64_t pad_columns = 0;    // extra columns around each separate operand: offset pad, stride + 2·pad
  bool mask_whole_batch0 = false;  // every key of batch 0 masked
  uint32_t rows_per_invocation = 0;  // 0: the device's default blocking
  bool workspace = false;            // repack K/V head-major first
};

class AttentionTest : public GpuTest {
 protected:
  void check(const Case& c, uint32_t seed) {
    AttentionShape s{c.batch, c.heads, c.head_dim, c.q_len, c.kv_len};
    const int64_t W = c.heads * c.head_dim;
    // Under a low allocation limit (DVS_LIMITS) the largest cases cannot even be uploaded: skip those.
    const int64_t rows = c.batch * std::max(c.q_len, c.kv_len) * (c.fused ? 3 * W : W + 2 * c.pad_columns);
    const int64_t most = std::max({rows, c.bias ? c.heads * c.q_len * c.kv_len : 0,
                                   c.workspace ? ops::attention_workspace_elements(s) : 0});
    if (uint64_t(most) * 4 > ctx().caps().max_memory_allocation_size) {
      std::cout << "[ SKIPPED  ] B" << c.batch << " H" << c.heads << " D" << c.head_dim << " Lq" << c.q_len << " Lk"
                << c.kv_len << ": a tensor over the allocation limit in force\n";
      return;
    }
    Tensor tq, tk, tv;
    if (c.fused) {
      ASSERT_EQ(c.q_len, c.kv_len);
    }
    const attention_ref::Operands ops_in = attention_ref::random_operands(ctx(), s, c.fused, c.pad_columns, seed);
    const HostOperand &hq = ops_in.hq, &hk = ops_in.hk, &hv = ops_in.hv;
    const AttentionOperand &q = ops_in.q, &k = ops_in.k, &v = ops_in.v;
    std::vector<float> bias, mask;
    Tensor tbias, tmask;
    AttentionOptions opt;
    opt.scale = c.scale;
    opt.rows_per_invocation = c.rows_per_invocation;
    if (c.bias) {
      bias = random_values(size_t(c.heads * c.q_len * c.kv_len), seed + 3, 2.0f);
      tbias = Tensor::upload(ctx(), HostTensor::from_f32({c.heads, c.q_len, c.kv_len}, bias));
      opt.bias = &tbias;
    }
    if (c.mask) {
      std::mt19937 gen(seed + 4);
      mask.resize(size_t(c.batch * c.kv_len));
      for (int64_t b = 0; b < c.batch; ++b)
        for (int64_t j = 0; j < c.kv_len; ++j)
          mask[size_t(b * c.kv_len + j)] = (c.mask_whole_batch0 && b == 0) ? 0.0f : float(gen() % 4 != 0);
      tmask = Tensor::upload(ctx(), HostTensor::from_f32({c.batch, c.kv_len}, mask));
      opt.key_mask = &tmask;
    }
    Tensor ws;
    if (c.workspace) {
      ws = Tensor::empty(ctx(), {ops::attention_workspace_elements(s)}, DType::f32);
      opt.workspace = &ws;
    }
    Tensor out = Tensor::empty(ctx(), {c.batch, c.q_len, W}, DType::f32);
    ops::run_now(ctx(), [&](vk::Recorder& rec) { ops::attention(rec, s, q, k, v, {out}, opt); });
    std::vector<float> got = out.download(ctx()).to_f32();
    std::vector<double> ref = reference(s, hq, hk, hv, c.scale, c.bias ? &bias : nullptr, c.mask ? &mask : nullptr);
    ASSERT_EQ(got.size(), ref.size());
    double vmax = 0;
    for (float x : hv.data) vmax = std::max(vmax, double(std::fabs(x)));
    const double tol = 2e-5 + 2e-5 * vmax;
    double worst = 0;
    size_t bad = 0;
    for (size_t i = 0; i < got.size(); ++i) {
      double e = std::fabs(double(got[i]) - ref[i]);
      if (!(e <= tol)) ++bad;
      if (!(e <= worst)) worst = e;
    }
    EXPECT_EQ(bad, 0u) << "B" << c.batch << " H" << c.heads << " D" << c.head_dim << " Lq" << c.q_len << " Lk"
                       << c.kv_len << ": worst error " << worst << " (tolerance " << tol << ")";
  }
};

TEST_F(AttentionTest, HeadDimsFromFourTo128) {
  uint32_t seed = 10;
  for (int64_t d : {4, 8, 12, 16, 36, 64, 128}) check({1, 2, d, 7, 33, 1.0f / std::sqrt(float(d))}, seed++);
}

TEST_F(AttentionTest, OddLengthsAndBatches) {
  check({2, 3, 16, 33, 129, 0.25f}, 30);
  check({1, 1, 64, 1, 1, 0.125f}, 31);
  check({3, 2, 8, 129, 7, 0.5f}, 32);
  check({1, 1, 32, 2, 65, 0.3f}, 33);
}

TEST_F(AttentionTest, StridedOperandsAndFusedQkv) {
  check({2, 2, 16, 17, 40, 0.25f, false, false, false, 8}, 40);
  check({2, 3, 64, 37, 37, 0.125f, false, false, true}, 41);
}

TEST_F(AttentionTest, T5RelativeBiasUnscaledAndKeyMask) {
  // Tiny-model T5: d_kv 8, 4 heads, 8 tokens; real-like: 226 tokens.
  check({1, 4, 8, 8, 8, 1.0f, true, false}, 50);
  check({2, 4, 8, 8, 8, 1.0f, true, true}, 51);
  check({1, 2, 64, 226, 226, 1.0f, true, false}, 52);
  check({2, 2, 16, 35, 70, 0.25f, false, true}, 53);
}

TEST_F(AttentionTest, FullyMaskedRowIsMeanOfValues) {
  // Batch 0 has every key masked (transformers then averages v over all keys); batch 1 is a normal mask.
  check({2, 2, 16, 9, 41, 0.25f, true, true, false, 0, true}, 60);
}

TEST_F(AttentionTest, TinyTransformerShape) {
  // Tiny CogVideoX: head_dim 16, joint [text; video] tokens, fused QKV.
  check({2, 2, 16, 74, 74, 0.25f, false, false, true}, 70);
}

TEST_F(AttentionTest, OtherRegisterBlockings) {
  // GPUs use one row per invocation; lavapipe 2, 4 or 8 by head_dim. Check the others here too.
  for (uint32_t rows : {1u, 3u}) {
    Case c{2, 2, 16, 70, 45, 0.25f, true, true};
    c.rows_per_invocation = rows;
    check(c, 80 + rows);
  }
}

TEST_F(AttentionTest, HeadMajorWorkspace) {
  Case fused{2, 3, 16, 37, 37, 0.25f, false, true, true};
  fused.workspace = true;
  check(fused, 90);
  Case strided{2, 4, 8, 9, 21, 1.0f, true, false, false, 4};
  strided.workspace = true;
  check(strided, 91);
  Case big{1, 2, 64, 5, 300, 0.125f};
  big.workspace = true;
  check(big, 92);
}

TEST_F(AttentionTest, RejectsBadLayouts) {
  Tensor t = Tensor::zeros(ctx(), {1, 4, 32}, DType::f32);
  AttentionShape s{1, 2, 16, 4, 4};
  auto run = [&](AttentionShape sh, AttentionOperand a) {
    ops::run_now(ctx(), [&](vk::Recorder& rec) { ops::attention(rec, sh, a, {t}, {t}, {t}); });
  };
  EXPECT_THROW(run(s, {t, 2, 32}), Error);                 // offset not a multiple of 4
  EXPECT_THROW(run(s, {t, 16, 32}), Error);                // columns past the row
  EXPECT_THROW(run({1, 2, 16, 5, 4}, {t}), Error);          // too few rows
  EXPECT_THROW(run({1, 2, 6, 4, 4}, {t}), Error);           // head_dim not a multiple of 4
  EXPECT_THROW(run({1, 2, 16, 4, 0}, {t}), Error);          // no keys
  Tensor small = Tensor::zeros(ctx(), {10}, DType::f32);
  AttentionOptions opt;
  opt.workspace = &small;
  EXPECT_THROW(ops::run_now(ctx(), [&](vk::Recorder& rec) { ops::attention(rec, s, {t}, {t}, {t}, {t}, opt); }),
               Error);  // workspace too small
}

}  // namespace
}  // namespace dvs::test
