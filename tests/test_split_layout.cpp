// Layout ops split so that no binding exceeds the limits: concat/split in row blocks and column pieces,
// permute in blocks along one output axis, patchify/unpatchify in frame chunks, gather/scatter with the
// indexed table bound in row ranges. Under binding=1KiB (256 words) every case below splits; each must give
// bitwise the result under the limits in force before, with more dispatches.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "support/gpu.hpp"
#include "support/texel_paths.hpp"
#include "support/split_check.hpp"
#include "tensor/ops_elementwise.hpp"
#include "tensor/ops_layout.hpp"

namespace dvs {
namespace {

constexpr const char* kSplitLimits = "binding=1KiB,groups=64";

class SplitLayout : public test::TexelPathsTest {
 protected:
  void expect_split_equal(const Shape& shape, DType dtype, const std::function<void(vk::Recorder&, const Tensor&)>& op,
                          const std::string& what, const HostTensor* init = nullptr) {
    test::expect_split_equal(ctx(), kSplitLimits, shape, dtype, op, what, init);
  }
};
DVS_TEXEL_PATHS(SplitLayout, SplitLayout);

HostTensor random_host(const Shape& s, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> d(-4.0f, 4.0f);
  std::vector<float> v(size_t(shape_numel(s)));
  for (float& x : v) x = d(rng);
  return HostTensor::from_f32(s, v);
}

Tensor random_tensor(vk::Context& ctx, const Shape& s, uint32_t seed) { return Tensor::upload(ctx, random_host(s, seed)); }

Tensor ids(vk::Context& ctx, int64_t m, int32_t lo, int32_t hi, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int32_t> d(lo, hi - 1);
  HostTensor h({m}, DType::i32);
  for (int64_t i = 0; i < m; ++i) h.as<int32_t>()[i] = d(rng);
  return Tensor::upload(ctx, h);
}

// A permutation of [0, n) (distinct scatter targets), first m taken.
Tensor distinct_ids(vk::Context& ctx, int64_t m, int32_t n, uint32_t seed) {
  std::vector<int32_t> all(static_cast<size_t>(n));
  for (int32_t i = 0; i < n; ++i) all[size_t(i)] = i;
  std::shuffle(all.begin(), all.end(), std::mt19937(seed));
  HostTensor h({m}, DType::i32);
  for (int64_t i = 0; i < m; ++i) h.as<int32_t>()[i] = all[size_t(i)];
  return Tensor::upload(ctx, h);
}

TEST_P(SplitLayout, ConcatAndSplitInRowBlocksAndColumnPieces) {
  // Bands of 3·13, 5·13 and 1·13 words per row; rows of 117 words (in blocks), and a row of 1 x 400 words (in
  // column pieces). Multiples of 4 take the vec4 shaders.
  for (const int64_t inner : {13, 12, 400}) {
    const int64_t R = inner == 400 ? 1 : 37;
    const Shape s1 = {R, 3, inner}, s2 = {R, 5, inner}, s3 = {R, 1, inner}, whole = {R, 9, inner};
    const Tensor a = random_tensor(ctx(), s1, 1), b = random_tensor(ctx(), s2, 2), c = random_tensor(ctx(), s3, 3);
    const std::string at = " inner " + std::to_string(inner);
    expect_split_equal(whole, DType::f32, [&](vk::Recorder& r, const Tensor& out) { ops::concat(r, {a, b, c}, out, 1); },
                       "concat" + at);
    const Tensor w = random_tensor(ctx(), whole, 4);
    // The three outputs as 64-byte aligned parts of one tensor (as separate allocations would be).
    const int64_t n1 = shape_numel(s1), n2 = shape_numel(s2), n3 = shape_numel(s3);
    const int64_t o2 = (n1 + 15) / 16 * 16, o3 = o2 + (n2 + 15) / 16 * 16;
    expect_split_equal({o3 + n3}, DType::f32, [&](vk::Recorder& r, const Tensor& out) {
      const vk::BufferView v = out.buffer();
      ops::split(r, w,
                 {Tensor::on(v.sub(0, n1 * 4), s1, DType::f32), Tensor::on(v.sub(o2 * 4, n2 * 4), s2, DType::f32),
                  Tensor::on(v.sub(o3 * 4, n3 * 4), s3, DType::f32)},
                 1);
    }, "split" + at);
  }
}

TEST_P(SplitLayout, PermuteInBlocksAlongOneOutputAxis) {
  struct Case {
    Shape shape;
    std::vector<int> perm;
  };
  // [B,F,C,HW] -> [B,C,F,HW] (odd and vec4 inner runs), heads [L, H, d] -> [H, L, d], a 3-axis rotation.
  const std::vector<Case> cases = {{{2, 7, 5, 11}, {0, 2, 1, 3}},
                                   {{2, 7, 3, 8}, {0, 2, 1, 3}},
                                   {{37, 3, 12}, {1, 0, 2}},
                                   {{9, 11, 13}, {2, 0, 1}}};
  for (const Case& c : cases) {
    SCOPED_TRACE("permute [" + shape_str(c.shape) + "]");
    const Tensor x = random_tensor(ctx(), c.shape, 5);
    Shape out(c.shape.size());
    for (size_t d = 0; d < out.size(); ++d) out[d] = c.shape[size_t(c.perm[d])];
    expect_split_equal(out, DType::f32, [&](vk::Recorder& r, const Tensor& y) { ops::permute(r, x, y, c.perm); },
                       "permute [" + shape_str(c.shape) + "]");
  }
}

TEST_P(SplitLayout, PatchifyInFrameChunks) {
  for (const int p : {1, 2}) {
    const Shape in = {2, 3, 2, 6, 10};  // 480 bytes a frame: two per 1KiB binding
    const Tensor x = random_tensor(ctx(), in, 6);
    const Shape tokens = {2, 3 * (6 / p) * (10 / p), 2 * p * p};
    expect_split_equal(tokens, DType::f32, [&](vk::Recorder& r, const Tensor& y) { ops::patchify(r, x, y, p); },
                       "patchify p=" + std::to_string(p));
    const Tensor t = random_tensor(ctx(), tokens, 7);
    expect_split_equal(in, DType::f32, [&](vk::Recorder& r, const Tensor& y) { ops::unpatchify(r, t, y, p); },
                       "unpatchify p=" + std::to_string(p));
  }
}

TEST_P(SplitLayout, GatherScatterBindTheTableInRowRanges) {
  for (const int64_t len : {7, 8}) {
    const int64_t rows = 301, m = 53;
    const Tensor table = random_tensor(ctx(), {rows, len}, 8);
    const Tensor gid = ids(ctx(), m, -3, int32_t(rows + 9), 9);  // some outside the table: zero rows
    const std::string at = " len " + std::to_string(len);
    expect_split_equal({m, len}, DType::f32, [&](vk::Recorder& r, const Tensor& out) { ops::gather_rows(r, table, gid, out); },
                       "gather" + at);
    const Tensor src = random_tensor(ctx(), {m, len}, 10), sid = distinct_ids(ctx(), m, int32_t(rows), 11);
    const HostTensor init = random_host({rows, len}, 12);
    expect_split_equal({rows, len}, DType::f32, [&](vk::Recorder& r, const Tensor& dst) { ops::scatter_rows(r, src, sid, dst); },
                       "scatter" + at, &init);
    const Tensor from = ids(ctx(), m, 0, int32_t(rows), 13);
    expect_split_equal({rows, len}, DType::f32,
                       [&](vk::Recorder& r, const Tensor& dst) { ops::gather_scatter_rows(r, table, from, sid, dst); },
                       "gather_scatter" + at, &init);
  }
}

}  // namespace
}  // namespace dvs
