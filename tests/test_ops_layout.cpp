// Layout ops against index-arithmetic references on the host. Data movement is exact: every comparison
// is bit for bit (tolerance 0).
#include <gtest/gtest.h>

#include <numeric>
#include <random>
#include <vector>

#include "io/npy.hpp"
#include "support/gpu.hpp"
#include "support/texel_paths.hpp"
#include "support/scoped_limits.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_layout.hpp"

namespace dvs {
namespace {

class LayoutOps : public test::GpuTest {};

// Permute and concat/split run twice: texel-buffer inputs (default) and forced storage buffers.
class LayoutOpsPaths : public test::TexelPathsTest {};
DVS_TEXEL_PATHS(LayoutOps, LayoutOpsPaths);

// Distinct values so any misplaced element shows.
std::vector<float> iota_values(int64_t n, float start = 0.5f) {
  std::vector<float> v(static_cast<size_t>(n));
  for (size_t i = 0; i < v.size(); ++i) v[i] = start + float(i);
  return v;
}

Tensor upload(vk::Context& ctx, const Shape& s, const std::vector<float>& v) {
  return Tensor::upload(ctx, HostTensor::from_f32(s, v));
}

Tensor upload_i32(vk::Context& ctx, const std::vector<int32_t>& v) {
  HostTensor h({int64_t(v.size())}, DType::i32);
  std::copy(v.begin(), v.end(), h.as<int32_t>());
  return Tensor::upload(ctx, h);
}

std::vector<int64_t> strides_of(const Shape& s) {
  std::vector<int64_t> st(s.size(), 1);
  for (size_t d = s.size(); d-- > 1;) st[d - 1] = st[d] * s[d];
  return st;
}

// Host permute: out[idx] = in[Σ idx_d · stride_in[perm[d]]].
std::vector<float> host_permute(const std::vector<float>& in, const Shape& s, const std::vector<int>& perm) {
  const size_t r = s.size();
  Shape os(r);
  for (size_t d = 0; d < r; ++d) os[d] = s[size_t(perm[d])];
  auto ist = strides_of(s);
  std::vector<float> out(in.size());
  std::vector<int64_t> idx(r, 0);
  for (size_t o = 0; o < out.size(); ++o) {
    int64_t rest = int64_t(o), off = 0;
    for (size_t d = r; d-- > 0;) {
      int64_t c = rest % os[d];
      rest /= os[d];
      off += c * ist[size_t(perm[d])];
    }
    out[o] = in[size_t(off)];
  }
  return out;
}

TEST_P(LayoutOpsPaths, PermuteMatchesReference) {
  struct Case {
    Shape s;
    std::vector<int> perm;
  };
  std::vector<Case> cases = {
      {{2, 3, 5, 7, 9}, {0, 2, 1, 3, 4}},   // BFCHW -> BCFHW, odd H·W (scalar)
      {{1, 13, 16, 6, 10}, {0, 2, 1, 3, 4}},  // tiny-model latent, H·W % 4 == 0 (vec4)
      {{1, 16, 13, 6, 10}, {0, 2, 1, 3, 4}},  // and back
      {{33, 7}, {1, 0}},                    // transpose
      {{2, 3, 4, 5, 6, 7}, {5, 3, 1, 0, 2, 4}},  // rank 6, nothing merges
      {{2, 1, 3, 1, 5}, {4, 3, 2, 1, 0}},   // size-1 axes dropped
      {{4, 8, 3}, {0, 1, 2}},               // identity: a plain copy
      {{3, 4, 8}, {1, 0, 2}},               // contiguous inner run of 8 (vec4)
      {{3, 5000, 2}, {1, 0, 2}},            // more output rows than the grid has in y (scalar)
      {{9000, 2, 4}, {1, 0, 2}},            // the same with vec4 rows
      {{4500, 2, 128}, {1, 0, 2}},          // long rows (one row per y step), more rows than the grid
  };
  for (const Case& c : cases) {
    if (test::over_allocation_limit(ctx(), uint64_t(shape_numel(c.s)) * 4, "permute [" + shape_str(c.s) + "]")) continue;
    auto in = iota_values(shape_numel(c.s));
    Shape os(c.s.size());
    for (size_t d = 0; d < os.size(); ++d) os[d] = c.s[size_t(c.perm[d])];
    Tensor ti = upload(ctx(), c.s, in), to = Tensor::empty(ctx(), os, DType::f32);
    ops::run_now(ctx(), [&](vk::Recorder& r) { ops::permute(r, ti, to, c.perm); });
    EXPECT_EQ(to.download(ctx()).to_f32(), host_permute(in, c.s, c.perm)) << "[" << shape_str(c.s) << "]";
  }
  Tensor a = Tensor::empty(ctx(), {2, 3}, DType::f32), b = Tensor::empty(ctx(), {2, 3}, DType::f32);
  EXPECT_THROW(ops::run_now(ctx(), [&](vk::Recorder& r) { ops::permute(r, a, b, {1, 0}); }), Error);  // wrong out
  EXPECT_THROW(ops::run_now(ctx(), [&](vk::Recorder& r) { ops::permute(r, a, a, {0, 0}); }), Error);
  Tensor big = Tensor::empty(ctx(), {2, 2, 2, 2, 2, 2, 2}, DType::f32), big2 = Tensor::empty(ctx(), {2, 2, 2, 2, 2, 2, 2}, DType::f32);
  EXPECT_THROW(ops::run_now(ctx(), [&](vk::Recorder& r) { ops::permute(r, big, big2, {6, 5, 4, 3, 2, 1, 0}); }), Error);
}

TEST_P(LayoutOpsPaths, ConcatAndSplitOnEveryAxis) {
  const Shape base = {2, 3, 5, 4};
  for (int axis = 0; axis < 4; ++axis) {
    for (int64_t extra : {1, 4}) {  // widths that break and keep 16-byte alignment of the bands
      Shape sa = base, sb = base;
      sb[size_t(axis)] = extra;
      Shape so = base;
      so[size_t(axis)] += extra;
      auto va = iota_values(shape_numel(sa)), vb = iota_values(shape_numel(sb), 10000.5f);
      Tensor ta = upload(ctx(), sa, va), tb = upload(ctx(), sb, vb), to = Tensor::empty(ctx(), so, DType::f32);
      ops::run_now(ctx(), [&](vk::Recorder& r) { ops::concat(r, {ta, tb}, to, axis); });
      // Reference: walk the output; coordinates along `axis` below base come from a, the rest from b.
      auto got = to.download(ctx()).to_f32();
      auto ost = strides_of(so), ast = strides_of(sa), bst = strides_of(sb);
      for (size_t o = 0; o < got.size(); ++o) {
        int64_t rest = int64_t(o), oa = 0, ob = 0;
        bool from_a = true;
        for (size_t d = 0; d < 4; ++d) {
          int64_t c = rest / ost[d];
          rest %= ost[d];
          if (int(d) == axis && c >= sa[d]) {
            from_a = false;
            c -= sa[d];
          }
          oa += c * ast[d];
          ob += c * bst[d];
        }
        ASSERT_EQ(got[o], from_a ? va[size_t(oa)] : vb[size_t(ob)]) << "axis " << axis << " at " << o;
      }
      // Split recovers both parts; negative axis accepted.
      Tensor ra = Tensor::empty(ctx(), sa, DType::f32), rb = Tensor::empty(ctx(), sb, DType::f32);
      ops::run_now(ctx(), [&](vk::Recorder& r) { ops::split(r, to, {ra, rb}, axis - 4); });
      EXPECT_EQ(ra.download(ctx()).to_f32(), va);
      EXPECT_EQ(rb.download(ctx()).to_f32(), vb);
    }
  }
  // The I2V transformer input: concat(noisy latent, image latent) on C of [B, F, C, H, W].
  Shape lat = {1, 13, 16, 6, 10};
  auto x = iota_values(shape_numel(lat)), img = iota_values(shape_numel(lat), -1e5f);
  Tensor tx = upload(ctx(), lat, x), ti = upload(ctx(), lat, img), cat = Tensor::empty(ctx(), {1, 13, 32, 6, 10}, DType::f32);
  ops::run_now(ctx(), [&](vk::Recorder& r) { ops::concat(r, {tx, ti}, cat, 2); });
  auto got = cat.download(ctx()).to_f32();
  for (int64_t f = 0; f < 13; ++f)
    for (int64_t c = 0; c < 32; ++c)
      for (int64_t p = 0; p < 60; ++p) {
        float want = c < 16 ? x[size_t((f * 16 + c) * 60 + p)] : img[size_t((f * 16 + c - 16) * 60 + p)];
        ASSERT_EQ(got[size_t((f * 32 + c) * 60 + p)], want);
      }
  // Many short rows: more rows than the grid has in y, so workgroups loop over rows.
  {
    auto va = iota_values(9000 * 3), vb = iota_values(9000, 1e6f);
    Tensor ta = upload(ctx(), {9000, 3}, va), tb = upload(ctx(), {9000, 1}, vb), to = Tensor::empty(ctx(), {9000, 4}, DType::f32);
    ops::run_now(ctx(), [&](vk::Recorder& r) { ops::concat(r, {ta, tb}, to, 1); });
    auto got = to.download(ctx()).to_f32();
    for (size_t r = 0; r < 9000; ++r)
      for (size_t c = 0; c < 4; ++c) ASSERT_EQ(got[r * 4 + c], c < 3 ? va[r * 3 + c] : vb[r]) << r << "," << c;
  }
  // Mismatched shapes are refused.
  Tensor bad = Tensor::empty(ctx(), {1, 13, 16, 6, 11}, DType::f32);
  EXPECT_THROW(ops::run_now(ctx(), [&](vk::Recorder& r) { ops::concat(r, {tx, bad}, cat, 2); }), Error);
}

TEST_F(LayoutOps, Concat16BitAndI32) {
  HostTensor a({3, 2}, DType::bf16), b({3, 4}, DType::bf16);
  for (int i = 0; i < 6; ++i) a.as<uint16_t>()[i] = uint16_t(i + 1);
  for (int i = 0; i < 12; ++i) b.as<uint16_t>()[i] = uint16_t(100 + i);
  Tensor ta = Tensor::upload(ctx(), a), tb = Tensor::upload(ctx(), b), to = Tensor::empty(ctx(), {3, 6}, DType::bf16);
  ops::run_now(ctx(), [&](vk::Recorder& r) { ops::concat(r, {ta, tb}, to, 1); });
  HostTensor got = to.download(ctx());
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 6; ++c)
      EXPECT_EQ(got.as<uint16_t>()[r * 6 + c], c < 2 ? a.as<uint16_t>()[r * 2 + c] : b.as<uint16_t>()[r * 4 + c - 2]);
  Tensor odd = Tensor::empty(ctx(), {3, 1}, DType::bf16), to2 = Tensor::empty(ctx(), {3, 3}, DType::bf16);
  EXPECT_THROW(ops::run_now(ctx(), [&](vk::Recorder& r) { ops::concat(r, {ta, odd}, to2, 1); }), Error);

  Tensor i1 = upload_i32(ctx(), {1, 2, 3}), i2 = upload_i32(ctx(), {4}), io = Tensor::empty(ctx(), {4}, DType::i32);
  ops::run_now(ctx(), [&](vk::Recorder& r) { ops::concat(r, {i1, i2}, io, 0); });
  HostTensor hi = io.download(ctx());
  for (int k = 0; k < 4; ++k) EXPECT_EQ(hi.as<int32_t>()[k], k + 1);
}

TEST_F(LayoutOps, PatchifyAndUnpatchifyFollowCogVideoX) {
  struct Case {
    int64_t C, H, W, p;
  };
  // p = 2 runs the vec4 shader, p = 1 and 3 the general one.
  // The last case has more (frame, patch row) pairs than the grid has in y.
  for (Case k : {Case{3, 6, 10, 2}, Case{16, 6, 10, 2}, Case{5, 9, 6, 3}, Case{2, 3, 5, 1}, Case{1, 2000, 6, 2}}) {
    const int64_t B = 2, F = 3, C = k.C, H = k.H, W = k.W, p = k.p, Hp = H / p, Wp = W / p;
    Shape s = {B, F, C, H, W};
    auto in = iota_values(shape_numel(s));
    Tensor ti = upload(ctx(), s, in), tp = Tensor::empty(ctx(), {B, F * Hp * Wp, C * p * p}, DType::f32);
    Tensor back = Tensor::empty(ctx(), s, DType::f32);
    ops::run_now(ctx(), [&](vk::Recorder& r) {
      ops::patchify(r, ti, tp, int(p));
      ops::unpatchify(r, tp, back, int(p));
    });
    auto got = tp.download(ctx()).to_f32();
    // token (f, hp, wp), feature (c, i, j) <- pixel (hp·p + i, wp·p + j) of channel c, frame f.
    for (int64_t b = 0; b < B; ++b)
      for (int64_t f = 0; f < F; ++f)
        for (int64_t hp = 0; hp < Hp; ++hp)
          for (int64_t wp = 0; wp < Wp; ++wp)
            for (int64_t c = 0; c < C; ++c)
              for (int64_t i = 0; i < p; ++i)
                for (int64_t j = 0; j < p; ++j) {
                  int64_t tok = (f * Hp + hp) * Wp + wp, feat = (c * p + i) * p + j;
                  int64_t src = (((b * F + f) * C + c) * H + hp * p + i) * W + wp * p + j;
                  ASSERT_EQ(got[size_t((b * F * Hp * Wp + tok) * C * p * p + feat)], in[size_t(src)]);
                }
    // unpatchify is the exact inverse (diffusers: reshape (B,F,Hp,Wp,C,p,p), permute (0,1,4,2,5,3,6)).
    EXPECT_EQ(back.download(ctx()).to_f32(), in);
  }
}

TEST_F(LayoutOps, UnpatchifyMatchesGoldenTransformerOutput) {
  // The golden pack's proj_out [1, F·Hp·Wp, p·p·Cout] and the model output [1, F, Cout, H, W] that diffusers
  // unpatchified from it: equal bit for bit.
  const std::string dir = test::golden_dir() + "/transformer/";
  HostTensor proj = read_npy(dir + "t999_proj_out.npy"), want = read_npy(dir + "output_t999.npy");
  ASSERT_EQ(want.shape.size(), 5u);
  Tensor tp = Tensor::upload(ctx(), proj), out = Tensor::empty(ctx(), want.shape, DType::f32);
  ops::run_now(ctx(), [&](vk::Recorder& r) { ops::unpatchify(r, tp, out, 2); });
  EXPECT_EQ(out.download(ctx()).to_f32(), want.to_f32());
}

TEST_F(LayoutOps, GatherScatterRows) {
  std::mt19937 rng(5);
  for (int64_t len : {1, 7, 8, 131, 256}) {  // single elements, odd rows, vec4 rows, long rows (y grid)
    const int64_t R = 37, m = 50;
    auto src = iota_values(R * len);
    std::vector<int32_t> idx(static_cast<size_t>(m));
    for (auto& i : idx) i = int32_t(rng() % R);
    idx[3] = -1;          // out of range: zero row
    idx[4] = int32_t(R);  // out of range: zero row
    Tensor ts = upload(ctx(), {R, len}, src), ti = upload_i32(ctx(), idx), tg = Tensor::empty(ctx(), {m, len}, DType::f32);
    ops::run_now(ctx(), [&](vk::Recorder& r) { ops::gather_rows(r, ts, ti, tg); });
    auto g = tg.download(ctx()).to_f32();
    for (int64_t i = 0; i < m; ++i)
      for (int64_t k = 0; k < len; ++k) {
        int32_t s = idx[size_t(i)];
        float want = s >= 0 && s < R ? src[size_t(s * len + k)] : 0.0f;
        ASSERT_EQ(g[size_t(i * len + k)], want) << "gather len " << len << " row " << i;
      }
    // Scatter a permutation of distinct rows into a larger destination; untouched rows keep their values.
    const int64_t D = 61;
    std::vector<int32_t> perm(static_cast<size_t>(D));
    std::iota(perm.begin(), perm.end(), 0);
    std::shuffle(perm.begin(), perm.end(), rng);
    std::vector<int32_t> didx(perm.begin(), perm.begin() + R);
    didx[0] = int32_t(D) + 5;  // skipped
    auto dst0 = iota_values(D * len, -5000.5f);
    Tensor td = upload(ctx(), {D, len}, dst0), tdi = upload_i32(ctx(), didx);
    ops::run_now(ctx(), [&](vk::Recorder& r) { ops::scatter_rows(r, ts, tdi, td); });
    auto want = dst0;
    for (int64_t i = 1; i < R; ++i)
      for (int64_t k = 0; k < len; ++k) want[size_t(didx[size_t(i)] * len + k)] = src[size_t(i * len + k)];
    EXPECT_EQ(td.download(ctx()).to_f32(), want) << "scatter len " << len;
  }
}

TEST_F(LayoutOps, GatherManyIndices) {
  // More index rows than the grid has in y: workgroups loop over rows.
  const int64_t R = 1000, m = 20000;
  auto src = iota_values(R);
  std::vector<int32_t> idx(static_cast<size_t>(m));
  for (size_t i = 0; i < idx.size(); ++i) idx[i] = int32_t((i * 7919) % R);
  Tensor ts = upload(ctx(), {R}, src), ti = upload_i32(ctx(), idx), tg = Tensor::empty(ctx(), {m}, DType::f32);
  ops::run_now(ctx(), [&](vk::Recorder& r) { ops::gather_rows(r, ts, ti, tg); });
  auto g = tg.download(ctx()).to_f32();
  for (size_t i = 0; i < idx.size(); ++i) ASSERT_EQ(g[i], src[size_t(idx[i])]) << i;
}

TEST_F(LayoutOps, StochasticLatentModulationInPlace) {
  // SLM on a tiny latent [F, C, H, W] = [3, 4, 5, 6] as elements: target cells take values of source cells.
  const int64_t n = 3 * 4 * 5 * 6;
  auto x = iota_values(n);
  std::vector<int32_t> targets, sources;
  for (int32_t e = 0; e < n; ++e) (e % 3 == 0 ? targets : sources).push_back(e);
  std::mt19937 rng(9);
  std::vector<int32_t> pick(targets.size());
  for (auto& s : pick) s = sources[rng() % sources.size()];
  Tensor tx = upload(ctx(), {n, 1}, x), tt = upload_i32(ctx(), targets), ts = upload_i32(ctx(), pick);
  ops::run_now(ctx(), [&](vk::Recorder& r) { ops::gather_scatter_rows(r, tx, ts, tt, tx); });
  auto want = x;
  for (size_t i = 0; i < targets.size(); ++i) want[size_t(targets[i])] = x[size_t(pick[i])];
  EXPECT_EQ(tx.download(ctx()).to_f32(), want);
}

}  // namespace
}  // namespace dvs
