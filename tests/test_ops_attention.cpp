// Attention (shaders/nn/attention.comp) against a plain double-precision softmax(q·kᵀ·scale + bias + mask)·v.
// Tolerance: |gpu − ref| ≤ 2e-5 + 2e-5·max|v| per element (fp32 accumulation over ≤ a few hundred keys,
// lavapipe's exp2 approximation; the output is a convex combination of v rows). A head_dim that is not a
// multiple of 4 runs on head-padded copies (ops_attention.hpp): same tolerance, and the output's columns
// outside its heads must keep what they held.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "support/attention_reference.hpp"
#include "support/expect_error.hpp"
#include "support/gpu.hpp"
#include "support/kernel_calls.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/coopmat_layout.hpp"
#include "tensor/kernel_tuning.hpp"
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
  int64_t out_offset = 0, out_extra = 0;  // out at this column of rows of H·D + out_extra columns
};

constexpr float kUntouched = 1234.5f;  // what the output's other columns hold before and after the call

class AttentionTest : public GpuTest {
 protected:
  // Returns the largest error against the reference.
  double check(const Case& c, uint32_t seed) {
    AttentionShape s{c.batch, c.heads, c.head_dim, c.q_len, c.kv_len};
    const int64_t W = c.heads * c.head_dim;
    // Under a low allocation limit (DVS_LIMITS) the largest cases cannot even be uploaded: skip those.
    const int64_t rows = c.batch * std::max(c.q_len, c.kv_len) * (c.fused ? 3 * W : W + 2 * c.pad_columns + c.out_extra);
    const int64_t most = std::max({rows, c.bias ? c.heads * c.q_len * c.kv_len : 0,
                                   c.workspace ? ops::attention_workspace_elements(s) : 0});
    if (uint64_t(most) * 4 > ctx().caps().max_memory_allocation_size) {
      std::cout << "[ SKIPPED  ] B" << c.batch << " H" << c.heads << " D" << c.head_dim << " Lq" << c.q_len << " Lk"
                << c.kv_len << ": a tensor over the allocation limit in force\n";
      return 0;
    }
    Tensor tq, tk, tv;
    EXPECT_TRUE(!c.fused || c.q_len == c.kv_len);
    EXPECT_LE(c.out_offset, c.out_extra);
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
    const int64_t os = W + c.out_extra;  // out's row stride
    const Tensor out = Tensor::upload(
        ctx(), HostTensor::from_f32({c.batch, c.q_len, os}, std::vector<float>(size_t(c.batch * c.q_len * os), kUntouched)));
    ops::run_now(ctx(), [&](vk::Recorder& rec) {
      ops::attention(rec, s, q, k, v, {out, c.out_offset, c.out_extra ? os : 0}, opt);
    });
    last_family_ = ops::attention_split_plan(ctx().caps(), s, q, k, v, {out, c.out_offset, c.out_extra ? os : 0}, opt).family;
    std::vector<float> got = out.download(ctx()).to_f32();
    std::vector<double> ref = reference(s, hq, hk, hv, c.scale, c.bias ? &bias : nullptr, c.mask ? &mask : nullptr);
    EXPECT_EQ(got.size(), size_t(c.batch * c.q_len * os));
    EXPECT_EQ(ref.size(), size_t(c.batch * c.q_len * W));
    double vmax = 0;
    for (float x : hv.data) vmax = std::max(vmax, double(std::fabs(x)));
    // A call on tensor cores (every test, where a tensor-core tuning is forced) has fp16 operands.
    const double fp16 = last_family_ == ops::KernelFamily::coopmat ? std::max(fp16_tolerance_, kFp16Tolerance) : fp16_tolerance_;
    const double tol = fp16 ? fp16 * (1 + vmax) : 2e-5 + 2e-5 * vmax;
    double worst = 0;
    size_t bad = 0, touched = 0;
    for (int64_t row = 0; row < c.batch * c.q_len; ++row)
      for (int64_t col = 0; col < os; ++col) {
        const float x = got[size_t(row * os + col)];
        if (col < c.out_offset || col >= c.out_offset + W) {
          touched += x != kUntouched;
          continue;
        }
        double e = std::fabs(double(x) - ref[size_t(row * W + col - c.out_offset)]);
        if (!(e <= tol)) ++bad;
        if (!(e <= worst)) worst = e;
      }
    const std::string what = "B" + std::to_string(c.batch) + " H" + std::to_string(c.heads) + " D" +
                             std::to_string(c.head_dim) + " Lq" + std::to_string(c.q_len) + " Lk" +
                             std::to_string(c.kv_len) + (c.fused ? " fused" : "") + (c.bias ? " bias" : "") +
                             (c.mask ? " mask" : "") + " scale " + std::to_string(c.scale);
    EXPECT_EQ(bad, 0u) << what << ": worst error " << worst << " (tolerance " << tol << ")";
    EXPECT_EQ(touched, 0u) << what << ": output columns outside the heads were written";
    return worst;
  }
  ops::KernelFamily last_family_ = ops::KernelFamily::texel;  // the kernel family of the last check()
  double fp16_tolerance_ = 0;  // > 0: tolerance fp16_tolerance_·(1 + max|v|) (tensor-core operands)
  // fp16 operands (q pre-scaled, k, v, p; 11-bit significands) with fp32 accumulation: the scores' rounding moves
  // the weights by ~1e-3 relative at these sizes.
  static constexpr double kFp16Tolerance = 5e-3;
};

TEST_F(AttentionTest, HeadDimsFromFourTo128) {
  uint32_t seed = 10;
  for (int64_t d : {4, 8, 12, 16, 36, 64, 128}) check({1, 2, d, 7, 33, 1.0f / std::sqrt(float(d))}, seed++);
}

// head_dim not a multiple of 4 (run on head-padded copies) and heads over 128 (one query row per invocation,
// up to 64 vec4 accumulators): 3 heads, batch 2, Lq ≠ Lk; operands at odd column offsets of wider rows (padded
// dims) and the output inside wider rows; with bias and mask; fused QKV; scale 1/sqrt(D) and 1.
TEST_F(AttentionTest, EveryHeadDimUpTo256) {
  uint32_t seed = 200;
  for (int64_t d : {1, 2, 3, 5, 6, 7, 13, 130, 255, 256}) {
    const float inv_sqrt = 1.0f / std::sqrt(float(d));
    const bool aligned = d % 4 == 0;  // 256: in place, offsets must stay multiples of 4
    Case plain{2, 3, d, 7, 11, inv_sqrt};
    plain.pad_columns = aligned ? 4 : 3;
    plain.out_offset = aligned ? 4 : 5;
    plain.out_extra = aligned ? 8 : 7;
    Case biased{2, 3, d, 7, 11, 1.0f, true, true};  // T5-like: unscaled, relative bias, key mask
    biased.pad_columns = aligned ? 0 : 1;
    Case fused{2, 3, d, 11, 11, inv_sqrt, false, true, true};
    fused.out_offset = aligned ? 0 : 1;
    fused.out_extra = aligned ? 0 : 2;
    Case fused_bias{2, 3, d, 9, 9, 1.0f, true, false, true};
    double worst[4] = {};
    const Case* cases[4] = {&plain, &biased, &fused, &fused_bias};
    for (int i = 0; i < 4; ++i) worst[i] = check(*cases[i], seed++);
    std::cout << "head_dim " << d << ": max error " << worst[0] << " (strided), " << worst[1] << " (bias + mask), "
              << worst[2] << " (fused + mask), " << worst[3] << " (fused + bias)\n";
  }
}

// Every head_dim from 1 to 24 and a few odd ones above (small shapes, odd offsets and strides everywhere).
TEST_F(AttentionTest, HeadDimSweep) {
  uint32_t seed = 300;
  double worst = 0;
  for (int64_t d = 1; d <= 24; ++d) {
    Case c{2, 2, d, 5, 6, 1.0f / std::sqrt(float(d)), d % 3 == 0, d % 2 == 0};
    c.pad_columns = d % 4 ? d % 5 : 4;
    c.out_offset = d % 4 ? 3 : 0;
    c.out_extra = d % 4 ? 6 : 0;
    worst = std::max(worst, check(c, seed++));
  }
  for (int64_t d : {33, 61, 66, 127, 129, 131, 190, 253}) {
    Case c{1, 2, d, 3, 5, 1.0f / std::sqrt(float(d)), false, true};
    c.pad_columns = d % 4 ? 1 : 0;
    worst = std::max(worst, check(c, seed++));
  }
  std::cout << "head_dim sweep: max error " << worst << "\n";
}

// Padded heads with the head-major workspace (sized for the padded head_dim) and with other register blockings.
TEST_F(AttentionTest, PaddedHeadDimWorkspaceAndBlockings) {
  Case ws{2, 3, 6, 9, 21, 0.4f, true, true};
  ws.workspace = true;
  ws.pad_columns = 2;
  std::cout << "head_dim 6, workspace: max error " << check(ws, 400) << "\n";
  for (uint32_t rows : {1u, 3u}) {
    Case c{2, 2, 130, 70, 13, 1.0f / std::sqrt(130.0f), true, true};
    c.rows_per_invocation = rows;
    std::cout << "head_dim 130, " << rows << " rows per invocation: max error " << check(c, 410 + rows) << "\n";
  }
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

// The tiled family (shaders/nn/attention_flash.comp) forced on lavapipe, on odd sizes: 64 query rows per
// workgroup, K/V tiles of 64 keys at D <= 64 and 32 at D = 72 and 128 (32 KiB of shared memory), so every
// length here ends in a partial tile; head_dim 40 and 72 as they are, 38 and 70 padded to 40 and 72.
// Under DVS_LIMITS the larger calls do not fit one storage binding and run on the texel kernel's splits.
TEST_F(AttentionTest, TiledFamilyOddSizes) {
  ops::ScopedTuningOverride tiled("attention=tiled");
  const bool forced = ctx().caps().forced_limits.any();
  uint32_t seed = 500;
  double worst = 0;
  const std::pair<int64_t, int64_t> lengths[] = {{1, 1}, {37, 45}, {130, 129}};
  for (int64_t d : {40, 64, 72, 128})
    for (int64_t heads : {1, 3})
      for (auto [lq, lk] : lengths) {
        Case c{2, heads, d, lq, lk, 1.0f / std::sqrt(float(d))};
        c.pad_columns = 4;
        c.out_offset = 4;
        c.out_extra = 8;
        worst = std::max(worst, check(c, seed++));
        if (!forced) {
          EXPECT_EQ(last_family_, ops::KernelFamily::tiled) << "D" << d << " H" << heads << " Lq" << lq;
        }
      }
  for (int64_t d : {38, 70, 64}) {  // fused QKV (Lq = Lk), one padded
    Case c{2, 3, d, 130, 130, 1.0f / std::sqrt(float(d)), false, false, true};
    worst = std::max(worst, check(c, seed++));
    if (!forced) {
      EXPECT_EQ(last_family_, ops::KernelFamily::tiled) << "fused D" << d;
    }
  }
  std::cout << "tiled family: max error " << worst << "\n";
}

// Calls the tiled kernel does not take (bias, key mask: T5) run on the texel kernel under attention=tiled;
// so does attention=coopmat on a device without cooperative matrices (it becomes tiled).
TEST_F(AttentionTest, TiledFamilyFallbacks) {
  {
    ops::ScopedTuningOverride tiled("attention=tiled");
    check({2, 4, 64, 37, 37, 1.0f, true, true}, 520);
    EXPECT_EQ(last_family_, ops::KernelFamily::texel);
    check({1, 2, 64, 45, 45, 1.0f, true, false, true}, 521);
    EXPECT_EQ(last_family_, ops::KernelFamily::texel);
    check({2, 2, 16, 35, 70, 0.25f, false, true}, 522);
    EXPECT_EQ(last_family_, ops::KernelFamily::texel);
  }
  if (!ops::device_tuning(ctx().caps()).coopmat.defined()) {
    ops::ScopedTuningOverride coop("attention=coopmat");
    check({2, 3, 64, 37, 45, 0.125f}, 523);
    if (!ctx().caps().forced_limits.any()) {
      EXPECT_EQ(last_family_, ops::KernelFamily::tiled);
    }
  }
}

// The coopmat family (shaders/nn/attention_flash_coopmat.comp) by value, where the device has tensor cores
// (lavapipe 26.1 in the tensor-core pass, GPUs). fp16 operands (q pre-scaled, k, v, p; 11-bit significands)
// with fp32 accumulation: tolerance 5e-3·(1 + max|v|) (the scores' rounding moves the weights by ~1e-3
// relative at these sizes). head_dim 16..64 in multiples of the fragment run on tensor cores (at 16x16x16:
// 16, 48, 64; at lavapipe's 8x8x8 also 40); 72 and 128 (over the 64-key tile) on the tiled kernel. Then
// other layouts of the same kernel: 1 and 2 subgroups, 32-key tiles (and 8 for the coopmat2 variant). Each twice
// where the device has VK_NV_cooperative_matrix2's row operations (lavapipe 26.1): the variant that keeps the
// softmax in the matrices (attention_flash_coopmat2.comp, the default there) and the KHR kernel
// (attention_coopmat2=off), each call checked to have run the shader its setting names.
TEST_F(AttentionTest, CoopmatFamilyByValue) {
  if (!ops::device_tuning(ctx().caps()).coopmat.defined()) GTEST_SKIP() << "no cooperative-matrix shape";
  const bool forced = ctx().caps().forced_limits.any();
  fp16_tolerance_ = kFp16Tolerance;
  uint32_t seed = 600;
  double worst = 0;
  std::string variant;  // "" or ",attention_coopmat2=off"
  auto run = [&](const std::string& layout, std::initializer_list<int64_t> dims,
                 std::initializer_list<std::pair<int64_t, int64_t>> lengths) {
    ops::ScopedTuningOverride coop("attention=coopmat" + layout + variant);
    const ops::DeviceTuning& t = ops::device_tuning(ctx().caps());
    const ops::CoopmatAttention a = ops::attention_coopmat_layout(t);
    const std::string shader = t.attention_coopmat2 && ctx().caps().cooperative_matrix2_row_ops && a.frag.n == a.frag.k
                                   ? "nn/attention_flash_coopmat2"
                                   : "nn/attention_flash_coopmat";
    for (int64_t d : dims)
      for (int64_t heads : {1, 3})
        for (auto [lq, lk] : lengths) {
          SCOPED_TRACE(a.describe() + variant);
          Case c{2, heads, d, lq, lk, 1.0f / std::sqrt(float(d))};
          c.pad_columns = 4;
          c.out_offset = 4;
          c.out_extra = 8;
          const uint64_t before = test::kernel_calls(ctx(), shader);
          worst = std::max(worst, check(c, seed++));
          if (last_family_ == ops::KernelFamily::coopmat) {
            EXPECT_GT(test::kernel_calls(ctx(), shader), before) << "D" << d << ": not run by " << shader;
          }
          const bool takes = ops::attention_coopmat_head_dim_unfit(a, d).empty();
          if (!forced) {
            EXPECT_EQ(last_family_, takes ? ops::KernelFamily::coopmat : ops::KernelFamily::tiled)
                << "D" << d << " H" << heads << " Lq" << lq << " Lk" << lk;
          }
        }
  };
  const bool both = ctx().caps().cooperative_matrix2_row_ops;
  for (const char* v : {"", ",attention_coopmat2=off"}) {
    if (!both && *v) break;
    variant = v;
    run("", {16, 48, 64, 40, 72, 128}, {{1, 1}, {37, 45}, {130, 129}, {64, 64}, {200, 1000}});
    for (int64_t d : {64, 62}) {  // fused QKV; 62 padded to 64
      ops::ScopedTuningOverride coop("attention=coopmat" + variant);
      Case c{2, 3, d, 130, 130, 1.0f / std::sqrt(float(d)), false, false, true};
      worst = std::max(worst, check(c, seed++));
    }
    for (const char* layout : {",attention_coopmat_subgroups=1", ",attention_coopmat_subgroups=2,attention_block_k=32"})
      run(layout, {16, 32}, {{37, 45}, {130, 129}});
    // 8 subgroups (the GPUs' 128 query rows at 16x16x16): only the coopmat2 variant holds them in shared memory.
    if (both && variant.empty()) run(",attention_coopmat_subgroups=8", {32, 64}, {{37, 45}, {200, 129}});
  }
  fp16_tolerance_ = 0;
  std::cout << "coopmat family: max error " << worst << "\n";
}

// The coopmat kernel's fp32 twin (attention_flash_coopmat_twin.comp: the same main(), staging, fp16 rounding,
// softmax and epilogue, the products as fp32 FMA), on lavapipe: what the coopmat kernel does besides its
// cooperative-matrix calls, by value. Tiles that fit 32 KiB with the twin's extra Q copy: D 16 with 64 or 32
// keys, D 32 with 32 keys; lengths with partial tiles and rows; fused QKV; D 30 padded to 32.
TEST_F(AttentionTest, CoopmatTwinByValue) {
  if (!ctx().caps().float16_arithmetic) GTEST_SKIP() << "no shaderFloat16";
  const bool forced = ctx().caps().forced_limits.any();
  fp16_tolerance_ = kFp16Tolerance;
  uint32_t seed = 700;
  double worst = 0;
  const std::pair<int64_t, int64_t> lengths[] = {{1, 1}, {37, 45}, {130, 129}, {64, 200}};
  for (auto [d, bk] : {std::pair<int64_t, int>{16, 64}, {16, 32}, {32, 32}}) {
    ops::ScopedTuningOverride twin("attention=tiled,attention_coopmat_twin=on,attention_block_k=" + std::to_string(bk));
    for (int64_t heads : {1, 3})
      for (auto [lq, lk] : lengths) {
        Case c{2, heads, d, lq, lk, 1.0f / std::sqrt(float(d))};
        c.pad_columns = 4;
        c.out_offset = 4;
        c.out_extra = 8;
        worst = std::max(worst, check(c, seed++));
        if (!forced) {
          EXPECT_EQ(last_family_, ops::KernelFamily::tiled);
        }
      }
    Case fused{2, 3, d == 32 ? 30 : d, 130, 130, 0.2f, false, false, true};
    worst = std::max(worst, check(fused, seed++));
  }
  // The twin at other lanes per subgroup (the coopmat kernel's softmax ownership): 8 lanes (2 rows a lane, as on
  // lavapipe at 16x16x16), 16 (a row a lane), 64 (4 lanes a row).
  for (const char* lanes : {"8", "16", "64"}) {
    ops::ScopedTuningOverride twin(std::string("attention=tiled,attention_coopmat_twin=on,attention_block_k=32,coopmat_lanes=") + lanes);
    for (auto [lq, lk] : {std::pair<int64_t, int64_t>{37, 45}, {130, 129}}) {
      Case c{2, 3, 32, lq, lk, 1.0f / std::sqrt(32.0f)};
      c.out_offset = 4;
      c.out_extra = 8;
      worst = std::max(worst, check(c, seed++));
      if (!forced) {
        EXPECT_EQ(last_family_, ops::KernelFamily::tiled) << lanes << " lanes";
      }
    }
  }
  fp16_tolerance_ = 0;
  std::cout << "coopmat twin: max error " << worst << "\n";
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
  EXPECT_THROW(run({1, 2, 6, 4, 4}, {t, 21, 32}), Error);   // head_dim 6 (padded, any offset): columns past the row
  EXPECT_THROW(run({1, 2, 6, 4, 4}, {t, -1, 32}), Error);   // negative offset
  expect_error([&] { run({1, 2, 0, 4, 4}, {t}); }, {"head_dim 0", "from 1 to 256"});
  expect_error([&] { run({1, 1, 257, 4, 4}, {t}); }, {"head_dim 257", "from 1 to 256"});
  EXPECT_THROW(run({1, 2, 16, 4, 0}, {t}), Error);          // no keys
  Tensor small = Tensor::zeros(ctx(), {10}, DType::f32);
  AttentionOptions opt;
  opt.workspace = &small;
  EXPECT_THROW(ops::run_now(ctx(), [&](vk::Recorder& rec) { ops::attention(rec, s, {t}, {t}, {t}, {t}, opt); }),
               Error);  // workspace too small
}

}  // namespace
}  // namespace dvs::test
