// Attention split over bounded sub-views (issue 10): limits forced low (ScopedLimits) make each kind of split
// happen at odd, tiny sizes. Every split result must equal the call under the limits in force without the
// scoped ones BITWISE: the same kernel computes every (row, head) with the same arithmetic in the same order
// (keys are split only at whole softmax blocks and the running state round-trips exactly through fp32
// memory; the repack only moves values). Each result is also checked against the double reference with the
// tolerance of test_ops_attention.cpp, and the split is proven: the plan says it split, and the recorder
// saw exactly the dispatches that plan implies. (Key chunks shorter than one softmax block cannot keep the
// order: those are compared within 1e-6·max|v|.)
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <iostream>
#include <string>
#include <vector>

#include "support/attention_reference.hpp"
#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "support/split_check.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_attention.hpp"

namespace dvs::test {
namespace {

using attention_ref::HostOperand;
using attention_ref::random_values;
using ops::AttentionOperand;
using ops::AttentionOptions;
using ops::AttentionShape;
using ops::AttentionSplit;

struct SplitCase {
  int64_t batch, heads, head_dim, q_len, kv_len;
  bool fused = false;  // q, k, v as column slices of one [B, L, 3·H·D] tensor (needs q_len == kv_len)
  bool bias = false, mask = false, workspace = false;
  uint32_t rows_per_invocation = 0;
  std::string limits;  // ScopedLimits spec that forces the split
};

int64_t ceil_div(int64_t a, int64_t b) { return (a + b - 1) / b; }

// Dispatches a split plan records: per batch element and head group, the repack chunks and the
// query-row × key chunks. A head-padded call: its copies, plus per group (all of one size here) the
// attention of that group on the padded copies (one dispatch, plus the repack with a workspace, when that
// attention is not split itself: head_group 0).
int64_t planned_dispatches(const SplitCase& c, const AttentionSplit& p) {
  if (p.padded_head_dim) {
    EXPECT_EQ(c.batch % p.pad_batch, 0);
    EXPECT_EQ(c.heads % p.pad_heads, 0);
    EXPECT_EQ(c.q_len % p.pad_q_rows, 0);
    SplitCase g = c;
    g.batch = p.pad_batch;
    g.heads = p.pad_heads;
    g.q_len = p.pad_q_rows;
    AttentionSplit inner = p;
    inner.padded_head_dim = 0;
    const int64_t groups = (c.batch / p.pad_batch) * (c.heads / p.pad_heads) * (c.q_len / p.pad_q_rows);
    return p.pad_copies + groups * (p.head_group ? planned_dispatches(g, inner) : 1 + (c.workspace ? 1 : 0));
  }
  const int64_t pack = p.repack ? ceil_div(c.kv_len, p.pack_rows) : 0;
  return c.batch * ceil_div(c.heads, p.head_group) * (pack + ceil_div(c.q_len, p.q_rows) * ceil_div(c.kv_len, p.keys));
}

class SplitAttentionTest : public GpuTest {
 protected:
  // Runs the case without and with the scoped limits; returns the split plan for the caller's assertions.
  AttentionSplit check(const SplitCase& c, uint32_t seed) {
    const AttentionShape s{c.batch, c.heads, c.head_dim, c.q_len, c.kv_len};
    const int64_t W = c.heads * c.head_dim;
    if (c.fused) {
      EXPECT_EQ(c.q_len, c.kv_len);
    }
    const attention_ref::Operands ops_in = attention_ref::random_operands(ctx(), s, c.fused, 0, seed);
    const HostOperand &hq = ops_in.hq, &hk = ops_in.hk, &hv = ops_in.hv;
    const AttentionOperand &q = ops_in.q, &k = ops_in.k, &v = ops_in.v;
    AttentionOptions opt;
    opt.scale = 1.0f / std::sqrt(float(c.head_dim));
    opt.rows_per_invocation = c.rows_per_invocation;
    std::vector<float> bias, mask;
    Tensor tbias, tmask, ws;
    if (c.bias) {
      bias = random_values(size_t(c.heads * c.q_len * c.kv_len), seed + 3, 2.0f);
      tbias = Tensor::upload(ctx(), HostTensor::from_f32({c.heads, c.q_len, c.kv_len}, bias));
      opt.bias = &tbias;
    }
    if (c.mask) {
      mask.resize(size_t(c.batch * c.kv_len));
      for (size_t i = 0; i < mask.size(); ++i) mask[i] = (i * 7 + seed) % 5 == 0 ? 0.0f : 1.0f;
      tmask = Tensor::upload(ctx(), HostTensor::from_f32({c.batch, c.kv_len}, mask));
      opt.key_mask = &tmask;
    }
    if (c.workspace) {
      ws = Tensor::empty(ctx(), {ops::attention_workspace_elements(s)}, DType::f32);
      opt.workspace = &ws;
    }
    Tensor out = Tensor::empty(ctx(), {c.batch, c.q_len, W}, DType::f32);

    auto run = [&](uint32_t& dispatches) {
      ops::run_now(ctx(), [&](vk::Recorder& rec) {
        const uint32_t before = rec.dispatch_count();
        ops::attention(rec, s, q, k, v, {out}, opt);
        dispatches = rec.dispatch_count() - before;
      });
      return out.download(ctx()).to_f32();
    };
    uint32_t base_dispatches = 0, split_dispatches = 0;
    const AttentionSplit base_plan = ops::attention_split_plan(ctx().caps(), s, q, k, v, {out}, opt);
    const std::vector<float> base = run(base_dispatches);
    AttentionSplit plan;
    std::vector<float> got;
    {
      ScopedLimits l(ctx(), c.limits);
      plan = ops::attention_split_plan(ctx().caps(), s, q, k, v, {out}, opt);
      const uint64_t noted = test::split_count(ctx(), "attention");
      got = run(split_dispatches);
      EXPECT_EQ(test::split_count(ctx(), "attention") - noted, 1u) << "a split call notes \"attention\" once";
    }
    const std::string what = "B" + std::to_string(c.batch) + " H" + std::to_string(c.heads) + " D" +
                             std::to_string(c.head_dim) + " Lq" + std::to_string(c.q_len) + " Lk" +
                             std::to_string(c.kv_len) + " under " + c.limits;
    EXPECT_FALSE(plan.whole) << what;
    if (!plan.whole) {
      EXPECT_EQ(int64_t(split_dispatches), planned_dispatches(c, plan)) << what;
    }
    if (base_plan.whole) {  // not so under DVS_LIMITS
      EXPECT_GT(split_dispatches, base_dispatches) << what;
    }

    double vmax = 0;
    for (float x : hv.data) vmax = std::max(vmax, double(std::fabs(x)));
    EXPECT_EQ(got.size(), base.size());
    size_t differ = 0;
    const std::vector<double> ref = attention_ref::reference(s, hq, hk, hv, opt.scale, c.bias ? &bias : nullptr,
                                                             c.mask ? &mask : nullptr);
    // The flash kernels (tiled, coopmat) take whole calls only: where one ran the unsplit call and the split
    // paths run the texel kernel, each is held to its own tolerance (fp16 operands on tensor cores) instead of
    // to the other bit for bit (two kernels agree bitwise only by the compiler's chance: tiled and texel did
    // under Mesa 22.3's LLVM 15, not under 26.1's LLVM 19).
    auto tolerance = [&](ops::KernelFamily f) {
      return f == ops::KernelFamily::coopmat ? 5e-3 * (1 + vmax) : 2e-5 + 2e-5 * vmax;
    };
    if (base_plan.family != plan.family) {
      for (size_t i = 0; i < base.size() && i < ref.size(); ++i) differ += !(std::fabs(base[i] - ref[i]) <= tolerance(base_plan.family));
      EXPECT_EQ(differ, 0u) << what << ": unsplit elements off the reference";
    } else if (plan.keys == c.kv_len || plan.keys % 4 == 0 || plan.whole) {
      for (size_t i = 0; i < got.size() && i < base.size(); ++i) differ += std::memcmp(&got[i], &base[i], 4) != 0;
      EXPECT_EQ(differ, 0u) << what << ": elements not bitwise equal to the unsplit call";
    } else {
      // Key chunks shorter than one softmax block (4 keys): other rescaling steps, same sums to ~1 ulp.
      for (size_t i = 0; i < got.size() && i < base.size(); ++i)
        differ += !(std::fabs(got[i] - base[i]) <= 1e-6 * vmax);
      EXPECT_EQ(differ, 0u) << what << ": elements off the unsplit call by more than 1e-6·max|v|";
    }

    const double tol = tolerance(plan.family);
    size_t bad = 0;
    double worst = 0;
    for (size_t i = 0; i < got.size() && i < ref.size(); ++i) {
      const double e = std::fabs(double(got[i]) - ref[i]);
      bad += !(e <= tol);
      worst = std::max(worst, e);
    }
    EXPECT_EQ(bad, 0u) << what << ": elements off the reference by more than " << tol;
    if (plan.padded_head_dim)
      std::cout << what << ": " << split_dispatches << " dispatches (" << plan.pad_copies << " copies), max error "
                << worst << "\n";
    return plan;
  }
};

// (a) binding: 37 query rows of 36 floats do not fit 5 KiB, 29 key rows do: query-row chunks, keys in place.
TEST_F(SplitAttentionTest, QueryRowChunks) {
  const AttentionSplit p = check({2, 3, 12, 37, 29, false, true, true, false, 0, "binding=5KiB"}, 10);
  EXPECT_LT(p.q_rows, 37);
}

// (b) texels: the relative-position bias [3, 37, 37] as R32F texels holds one head (1369) but not two in
// 1400 texels: one head per group.
TEST_F(SplitAttentionTest, HeadGroups) {
  const AttentionSplit p = check({2, 3, 12, 37, 37, true, true, true, false, 0, "texels=1400"}, 20);
  EXPECT_LT(p.head_group, 3);
}

// (c) binding: one head's K strided through the fused rows (36 rows × 108 floats) does not fit 8 KiB, so K/V
// are repacked head-major, in token-row chunks (19 fused rows fit); with and without a caller workspace.
TEST_F(SplitAttentionTest, RepackChunks) {
  for (bool workspace : {false, true}) {
    const AttentionSplit p = check({2, 3, 12, 37, 37, true, false, true, workspace, 0, "binding=8KiB"}, 30);
    EXPECT_TRUE(p.repack);
    EXPECT_LT(p.pack_rows, 37);
  }
}

// Keys: at 1 KiB not even one head's 37 keys × 12 floats fit: keys in chunks (whole blocks of the online
// softmax: bitwise equal), the running state carried between dispatches; with bias and mask windowed alike.
// At head_dim 128 a chunk holds one key, less than a block: equal within 1e-6·max|v| instead.
TEST_F(SplitAttentionTest, KeyChunks) {
  const AttentionSplit p = check({2, 3, 12, 37, 37, true, true, true, false, 0, "binding=1KiB"}, 40);
  EXPECT_LT(p.keys, 37);
  EXPECT_TRUE(p.repack);
  const AttentionSplit pw = check({2, 3, 12, 37, 37, true, true, true, true, 0, "binding=1KiB"}, 42);  // workspace
  EXPECT_LT(pw.keys, 37);
  const uint64_t state_bytes = uint64_t(pw.q_rows * pw.head_group * (12 + 4) * 4);
  EXPECT_GE(pw.scratch_bytes, state_bytes);
  EXPECT_LT(pw.scratch_bytes, state_bytes + 256) << "only the running state outside the workspace";
  const AttentionSplit p2 = check({1, 2, 128, 5, 9, false, true, false, false, 0, "binding=1KiB"}, 41);
  EXPECT_LT(p2.keys, 4);
}

// (d) groups: 64 workgroups per grid dimension. Heads are on y (67 heads, with their bias), batch on z
// (65 elements), query blocks on x (4100 rows at one row per invocation: 65 blocks of 64).
TEST_F(SplitAttentionTest, GridLimits) {
  const AttentionSplit heads = check({1, 67, 4, 9, 7, false, true, false, false, 0, "groups=64"}, 50);
  EXPECT_LE(heads.head_group, 64);
  check({65, 1, 4, 5, 3, false, false, true, false, 0, "groups=64"}, 51);
  const AttentionSplit rows = check({1, 1, 4, 4100, 5, false, false, false, false, 1, "groups=64"}, 52);
  EXPECT_LT(rows.q_rows, 4100);
}

// Head-padded calls (head_dim 6, 5, 7: q, k, v copied with each head widened to 8 columns, the output
// copied back into the first columns of each head). Under 2 KiB bindings the copies of 37 token rows go in
// chunks of rows (more than the 4 copies of an unsplit call) and the attention on the padded copies splits
// as in (a)-(c); under 300 texels the R32F source windows of the copies are the limit; under 64 workgroups
// per grid dimension the copies' grids (at most 64·64·64 elements each: 70000 rows × 2 heads of 4 padded
// columns take 3 dispatches, 70000 × 2 × 3 back take 2).
TEST_F(SplitAttentionTest, PaddedHeadDimCopies) {
  const AttentionSplit p = check({2, 3, 6, 37, 29, false, true, true, false, 0, "binding=2KiB"}, 60);
  EXPECT_EQ(p.padded_head_dim, 8);
  EXPECT_GT(p.pad_copies, 4);
  EXPECT_EQ(p.pad_batch, 2) << "the padded copies fit one allocation: one group";
  const AttentionSplit pf = check({2, 3, 5, 37, 37, true, true, true, false, 0, "binding=2KiB"}, 61);  // fused
  EXPECT_GT(pf.pad_copies, 4);
  const AttentionSplit pw = check({2, 3, 7, 37, 37, true, false, true, true, 0, "binding=2KiB"}, 62);  // workspace
  EXPECT_GT(pw.pad_copies, 4);
  const AttentionSplit pt = check({2, 3, 6, 37, 29, false, false, false, false, 0, "texels=300"}, 63);
  EXPECT_GT(pt.pad_copies, 4);
  const AttentionSplit pg = check({1, 2, 3, 70000, 5, false, false, true, false, 1, "groups=64"}, 64);
  EXPECT_GE(pg.pad_copies, 3 + 1 + 1 + 2);  // exactly that unless DVS_LIMITS cuts the copies further
}

// The padded copies of the whole call do not fit one allocation (each is one Recorder scratch; head_dim 255
// padded to 256: 1 KiB per token row and head) under 64 KiB allocations: groups of batch elements (20 rows
// × 3 heads of one batch element fit), of heads (40 rows: one head), of query rows of one head (126 query
// rows, 63 at a time: 64 KiB less the 256 B alignment room; the head's 16 keys fit). Each group's attention runs unsplit on its copies, with its
// bias rows and mask rows.
TEST_F(SplitAttentionTest, PaddedHeadDimGroups) {
  const AttentionSplit pb = check({2, 3, 255, 20, 20, false, true, true, false, 0, "alloc=64KiB"}, 70);
  EXPECT_EQ(pb.pad_batch, 1);
  EXPECT_EQ(pb.pad_heads, 3);
  const AttentionSplit ph = check({2, 3, 255, 40, 40, true, true, true, false, 0, "alloc=64KiB"}, 71);
  EXPECT_EQ(ph.pad_batch, 1);
  EXPECT_EQ(ph.pad_heads, 1);
  const AttentionSplit pq = check({2, 3, 255, 126, 16, false, true, true, false, 0, "alloc=64KiB"}, 72);
  EXPECT_EQ(pq.pad_heads, 1);
  EXPECT_EQ(pq.pad_q_rows, 63);
  EXPECT_LE(pq.scratch_bytes, 4u * 64 * 1024) << "four padded regions of at most one allocation each";
}

// The real sizes under lavapipe's limits (128 MiB bindings), planned only (nothing allocated: the operands
// are views of a placeholder buffer handle that is never bound). CogVideoX 49×480×720: fused QKV
// [2, 17776, 9216] (1.31 GB) must split, with K/V repacked head-major and each head's 17776 keys in one
// dispatch; T5-XXL at 226 tokens fits whole.
TEST(SplitAttentionPlan, RealSizesUnderLavapipeLimits) {
  vk::DeviceCaps caps;
  caps.type = VK_PHYSICAL_DEVICE_TYPE_CPU;
  caps.max_storage_buffer_range = 128ull << 20;
  caps.max_texel_buffer_elements = 1ull << 27;
  caps.max_memory_allocation_size = 2ull << 30;
  caps.min_storage_buffer_offset_alignment = caps.min_texel_buffer_offset_alignment = 16;
  for (uint32_t& g : caps.max_workgroup_count) g = 65535;
  const vk::BufferView placeholder{reinterpret_cast<VkBuffer>(uintptr_t{0x1000}), 0, 1ull << 40, nullptr};
  auto plan = [&](const AttentionShape& s, const ops::AttentionOptions& opt) {
    const Tensor qkv = Tensor::on(placeholder, {s.batch, s.q_len, 3 * s.heads * s.head_dim}, DType::f32);
    const Tensor out = Tensor::on(placeholder, {s.batch, s.q_len, s.heads * s.head_dim}, DType::f32);
    return ops::attention_split_plan(caps, s, ops::fused_qkv_operand(qkv, 0, s.heads, s.head_dim),
                                     ops::fused_qkv_operand(qkv, 1, s.heads, s.head_dim),
                                     ops::fused_qkv_operand(qkv, 2, s.heads, s.head_dim), {out}, opt);
  };
  const AttentionShape cog{2, 48, 64, 17776, 17776};
  const AttentionSplit p = plan(cog, {});
  EXPECT_FALSE(p.whole);
  EXPECT_TRUE(p.repack);
  EXPECT_EQ(p.keys, 17776);
  EXPECT_GE(p.head_group, 16);  // a few head groups of 4.5 MB per head's K
  EXPECT_GE(p.q_rows, 2048);
  EXPECT_LE(p.scratch_bytes, 2 * caps.max_storage_buffer_range);  // head-major K and V of one head group
  const SplitCase c{2, 48, 64, 17776, 17776};
  std::cout << "CogVideoX real size: head group " << p.head_group << ", q rows " << p.q_rows << ", repack rows "
            << p.pack_rows << ", " << planned_dispatches(c, p) << " dispatches, " << p.scratch_bytes << " B scratch\n";
  EXPECT_LE(planned_dispatches(c, p), 64) << "head group " << p.head_group << ", q rows " << p.q_rows << ", pack rows "
                                          << p.pack_rows;

  const AttentionShape t5{2, 64, 64, 226, 226};
  const Tensor bias = Tensor::on(placeholder, {64, 226, 226}, DType::f32);
  const Tensor mask = Tensor::on(placeholder, {2, 226}, DType::f32);
  ops::AttentionOptions opt;
  opt.bias = &bias;
  opt.key_mask = &mask;
  EXPECT_TRUE(plan(t5, opt).whole);
}

}  // namespace
}  // namespace dvs::test
