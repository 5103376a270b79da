// The tensor-core linear kernel's own paths (the fixture: support/linear_test.hpp; instantiated with the other
// LinearTest cases in test_ops_linear.cpp, so these run on every family and skip where the family is not coopmat):
// its two load paths and workgroup order, f16 outputs, the per-shape tile table, the ablations the device script
// times; and, on devices without tensor cores, that the kernel is embedded and that asking for it runs tiled.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/linear_test.hpp"
#include "support/scoped_limits.hpp"
#include "support/split_check.hpp"
#include "vk/shader_registry.hpp"

namespace dvs {
namespace {

// LinearTest, Options, make_host, random_values and the ops names they use (support/linear_test.hpp).
using namespace test;

// The tensor-core kernel's two load paths and its workgroup order, by value and by the pipeline that ran:
// shapes whose K, strides and offsets are multiples of 8 take the 16-byte loads (each weight type widens its
// own way), an X offset of 3 elements the element loads; M spans 7 tile rows and a part, so bands of 3 tile
// rows end in a partial band (a tile the remapped order missed keeps Y's sentinel, one visited twice is
// harmless but one missed is not). Where the tuning turns the vector loads off, every call takes element loads.
TEST_P(LinearTest, CoopmatLoadPathsAndBands) {
  if (family() != ops::KernelFamily::coopmat) GTEST_SKIP() << "tensor-core family only";
  const std::string base = GetParam();
  ops::ScopedTuningOverride bands(base + (base.empty() ? "" : ",") + "linear_coopmat_group_m=3");
  vk::Context& c = ctx();
  LinearShape probe;
  probe.m = probe.n = probe.k = 8;
  const LinearKernel kern = ops::choose_linear_kernel(c, probe, DType::f32);
  const int64_t M = kern.tile_m * 7 + 5, N = kern.tile_n * 2 + 3;
  // The linear_coopmat pipelines created with bands of 3 and this weight code and load path.
  auto ran = [&](uint32_t wcode, bool vec) {
    bool found = false;
    c.pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name == "linalg/linear_coopmat" && pl.spec.size() == 15 && pl.spec[2] == wcode &&
          pl.spec[10] == (vec ? 1u : 0u) && pl.spec[11] == 3 && pl.spec[12] == 0 && pl.spec[13] == 0)
        found = true;
    });
    return found;
  };
  const bool vector_loads = ops::device_tuning(c.caps()).linear_coopmat_vector_loads;
  const std::pair<DType, uint32_t> types[] = {{DType::f32, 0}, {DType::f16, 1}, {DType::bf16, 2}};
  for (const auto& [dt, code] : types) {
    Options o;
    o.w_dtype = dt;
    o.bias = true;
    check(M, N, 48, o);
    EXPECT_TRUE(ran(code, vector_loads)) << dtype_name(dt) << ": the aligned call did not take the expected path";
  }
  Options u;
  u.w_dtype = DType::bf16;
  u.x_lead = 3;
  check(M, N, 48, u);
  EXPECT_TRUE(ran(2, false)) << "the misaligned call did not take the element loads";
}

// Y stored f16 by the tensor-core kernel (the FFN's GELU output, the next GEMM's X): each value the f32 Y of the
// same call rounded to nearest even, bit for bit, written in pairs into a padded, batched view at an offset (the
// padding and the elements around the view stay untouched); refused where a pair could straddle a row (odd N),
// with a residual, and on the other families.
TEST_P(LinearTest, CoopmatHalfOutputs) {
  if (family() != ops::KernelFamily::coopmat) GTEST_SKIP() << "tensor-core family only";
  vk::Context& c = ctx();
  const int64_t B = 2, M = 37, N = 46, K = 48, ldy = N + 2, lead = 6;
  std::vector<float> xv = random_values(size_t(B * M * K), 5), wv = random_values(size_t(N * K), 6),
                     bv = random_values(size_t(N), 7);
  Tensor x = Tensor::upload(c, make_host({B * M * K}, DType::f16, xv));
  Tensor w = Tensor::upload(c, make_host({N, K}, DType::bf16, wv));
  LinearEpilogue ep;
  ep.bias = Tensor::upload(c, make_host({N}, DType::f32, bv));
  ep.activation = Activation::gelu_tanh;
  LinearShape s;
  s.batch = B, s.m = M, s.n = N, s.k = K, s.x_batch_stride = M * K, s.y_batch_stride = M * ldy, s.y_row_stride = ldy;
  Tensor y32 = Tensor::empty(c, {B * M * ldy}, DType::f32);
  Tensor big = Tensor::zeros(c, {lead + B * M * ldy + 4}, DType::f16);
  Tensor y16 = big.rows(lead, B * M * ldy);
  ops::run_now(c, [&](vk::Recorder& rec) {
    ops::linear_batched(rec, x, w, y32, s, ep);
    ops::linear_batched(rec, x, w, y16, s, ep);
  });
  const std::vector<float> f = y32.download(c).to_f32();
  const HostTensor h = big.download(c);
  size_t differ = 0, touched = 0;
  for (int64_t i = 0; i < int64_t(h.numel()); ++i) {
    const int64_t o = i - lead, col = o % ldy;
    const bool inside = o >= 0 && o < B * M * ldy && col < N;
    if (inside) differ += h.as<uint16_t>()[size_t(i)] != f32_to_f16(f[size_t(o)]);
    else touched += h.as<uint16_t>()[size_t(i)] != 0;
  }
  EXPECT_EQ(differ, 0u) << "f16 outputs that are not the f32 ones rounded";
  EXPECT_EQ(touched, 0u) << "writes outside the view or into the padding";
  // Cut into chunks by small bindings: 31 rows of W (96 B each) fit 3 KiB, so the column chunks are made even (a
  // pair must not straddle two chunks) and the bits stay the whole call's.
  if (!c.caps().forced_limits.any()) {
    Tensor big_split = Tensor::zeros(c, {lead + B * M * ldy + 4}, DType::f16);
    {
      test::ScopedLimits small(c, "binding=3KiB");
      const uint32_t dispatches = test::run_counted(c, [&](vk::Recorder& rec) {
        ops::linear_batched(rec, x, w, big_split.rows(lead, B * M * ldy), s, ep);
      });
      EXPECT_GT(dispatches, 1u) << "the 3 KiB bindings did not split the call";
    }
    EXPECT_EQ(big_split.download(c).data, h.data) << "the split f16 call gives other bytes than the whole one";
  }

  std::vector<float> wodd_v(wv.begin(), wv.begin() + (N - 1) * K);
  Tensor odd = Tensor::empty(c, {M, N - 1}, DType::f16), wodd = Tensor::upload(c, make_host({N - 1, K}, DType::f32, wodd_v));
  const Tensor x2 = x.rows(0, M * K).reshape({M, K});
  test::expect_error([&] { ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x2, wodd, odd); }); },
                     {"an f16 y needs the coopmat family, N and y's strides even and no residual"});
  Tensor ye = Tensor::zeros(c, {M, N}, DType::f16);
  test::expect_error([&] {
    ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x2, w, ye, LinearEpilogue{.residual = ye}); });
  }, {"no residual"});
  ops::ScopedTuningOverride tiled("linear=tiled");
  test::expect_error([&] { ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x2, w, ye); }); },
                     {"an f16 y needs the coopmat family"});
}

// The per-shape tile table by value: a call with N >= 40 takes row 1's layout, one with M <= 20 (and N under 40)
// row 2's, the others the tuning's linear_coopmat, each checked against the reference and by the pipeline that ran
// (its layout's specialization constants).
TEST_P(LinearTest, CoopmatPerShapeTiles) {
  if (family() != ops::KernelFamily::coopmat) GTEST_SKIP() << "tensor-core family only";
  const std::string base = GetParam();
  ops::ScopedTuningOverride rows(base + (base.empty() ? "" : ",") +
                                 "linear_coopmat_by_shape=n>=40:1x1x1x1x8+m<=20:4x2x1x3x16");
  vk::Context& c = ctx();
  const CoopmatTile fallback = ops::device_tuning(c.caps()).linear_coopmat;
  auto ran = [&](const CoopmatTile& t) {
    bool found = false;
    c.pipelines().for_each([&](const vk::Pipeline& pl) {
      if (pl.name == "linalg/linear_coopmat" && pl.spec.size() == 15 && pl.spec[0] == uint32_t(t.sg_m) &&
          pl.spec[1] == uint32_t(t.sg_n) && pl.spec[3] == uint32_t(t.k) && pl.spec[5] == uint32_t(t.frags_m) &&
          pl.spec[6] == uint32_t(t.frags_n))
        found = true;
    });
    return found;
  };
  const struct {
    int64_t m, n, k;
    CoopmatTile tile;
  } cases[] = {{37, 45, 48, {1, 1, 1, 1, 8}}, {19, 24, 40, {4, 2, 1, 3, 16}}, {37, 24, 48, fallback}};
  for (const auto& k : cases) {
    LinearShape s;
    s.m = k.m, s.n = k.n, s.k = k.k;
    const LinearKernel kern = ops::choose_linear_kernel(c, s, DType::bf16);
    EXPECT_EQ(kern.coopmat.sg_m, k.tile.sg_m) << k.m << "x" << k.n;
    EXPECT_EQ(kern.coopmat.frags_n, k.tile.frags_n) << k.m << "x" << k.n;
    Options o;
    o.w_dtype = DType::bf16;
    o.bias = true;
    check(k.m, k.n, k.k, o);
    EXPECT_TRUE(ran(k.tile)) << k.m << "x" << k.n << ": its layout's pipeline did not run";
  }
}

// The ablations the device script's sweep times (measurements only) are live: without MMA an aligned call's Y
// is its bias alone; without global loads Y no longer depends on X (two different X give the same Y).
TEST_P(LinearTest, CoopmatAblationsAreLive) {
  if (family() != ops::KernelFamily::coopmat) GTEST_SKIP() << "tensor-core family only";
  const std::string base = GetParam();
  vk::Context& c = ctx();
  const int64_t M = 37, N = 45, K = 48;
  auto run = [&](const char* ablation, uint32_t seed) {
    ops::ScopedTuningOverride t(base + (base.empty() ? "" : ",") + "linear_coopmat_ablation=" + ablation);
    std::vector<float> xv = random_values(size_t(M * K), seed), wv = random_values(size_t(N * K), 2),
                       bv = random_values(size_t(N), 3);
    Tensor x = Tensor::upload(c, make_host({M, K}, DType::f32, xv));
    Tensor w = Tensor::upload(c, make_host({N, K}, DType::bf16, wv));
    Tensor y = Tensor::empty(c, {M, N}, DType::f32);
    LinearEpilogue ep;
    ep.bias = Tensor::upload(c, make_host({N}, DType::f32, bv));
    ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x, w, y, ep); });
    return std::make_pair(y.download(c).to_f32(), bv);
  };
  const auto [no_mma, bias] = run("no_mma", 1);
  for (int64_t m = 0; m < M; ++m)
    for (int64_t n = 0; n < N; ++n) ASSERT_EQ(no_mma[size_t(m * N + n)], bias[size_t(n)]) << m << "," << n;
  EXPECT_EQ(run("no_global_loads", 1).first, run("no_global_loads", 7).first);
  EXPECT_NE(run("none", 1).first, run("none", 7).first);
}

// The tensor-core kernel cannot run on lavapipe (no VK_KHR_cooperative_matrix): it is embedded (compiled by
// glslang 15 and checked by spirv-val at build time), and asking for it on a device without a coopmat shape
// runs the tiled kernel instead.
class LinearCoopmatTest : public test::GpuTest {};

TEST_F(LinearCoopmatTest, ShadersEmbedded) {
  const std::vector<std::string> names = vk::shader_names();
  for (const char* want : {"linalg/linear_coopmat", "linalg/linear_tiled", "bench/coopmat_mma_rate"})
    EXPECT_NE(std::find(names.begin(), names.end(), want), names.end()) << want;
}

TEST_F(LinearCoopmatTest, FallsBackToTiledWithoutCoopmat) {
  vk::Context& c = ctx();
  if (ops::device_tuning(c.caps()).coopmat.defined()) GTEST_SKIP() << "the device has cooperative matrices";
  LinearShape s;
  s.m = 37;
  s.n = 45;
  s.k = 24;
  for (const char* o : {"linear=coopmat", "gpu-coopmat"}) {
    ops::ScopedTuningOverride t(o);
    const LinearKernel k = ops::choose_linear_kernel(c, s, DType::bf16);
    EXPECT_EQ(k.family, ops::KernelFamily::tiled) << o;
  }
  {
    // The tiled kernel caps its tile at 64x64 (8x8 register blocks did not finish on the H100).
    ops::ScopedTuningOverride big("linear=tiled,linear_tile_m=128,linear_tile_n=128,linear_tile_k=32");
    const LinearKernel k = ops::choose_linear_kernel(c, s, DType::f32);
    EXPECT_EQ(k.tile_m, 64);
    EXPECT_EQ(k.tile_n, 64);
    EXPECT_EQ(k.tile_k, 16);
  }
  ops::ScopedTuningOverride t("gpu-coopmat");
  // And it runs: y = x·wᵀ on the tiled kernel.
  std::vector<float> xv = random_values(37 * 24, 1), wv = random_values(45 * 24, 2);
  Tensor x = Tensor::upload(c, make_host({37, 24}, DType::f32, xv));
  Tensor w = Tensor::upload(c, make_host({45, 24}, DType::bf16, wv));
  Tensor y = Tensor::empty(c, {37, 45}, DType::f32);
  LinearEpilogue ep;
  ep.fp16_operands_ok = false;
  ops::run_now(c, [&](vk::Recorder& rec) { ops::linear(rec, x, w, y, ep); });
  std::vector<float> got = y.download(c).to_f32();
  for (int m = 0; m < 37; ++m)
    for (int n = 0; n < 45; ++n) {
      double acc = 0;
      for (int kk = 0; kk < 24; ++kk) acc += double(xv[size_t(m * 24 + kk)]) * wv[size_t(n * 24 + kk)];
      EXPECT_NEAR(got[size_t(m * 45 + n)], acc, 1e-4);
    }
}

}  // namespace
}  // namespace dvs
