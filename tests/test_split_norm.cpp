// Norms split over bounded sub-ranges when forced limits make x/y exceed one binding or the grid: row chunks
// (layernorm with adaLN modulation, chunks crossing batch boundaries and the text/video split; per-head
// layernorm on a fused QKV buffer; RMSNorm), GroupNorm statistics over chunks of whole groups and the apply
// pass over chunks of planes. The result must equal the unsplit call bitwise (same per-row / per-group
// arithmetic), and the split must really happen (more dispatches). Odd sizes throughout.
#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "support/split_check.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_norm.hpp"
#include "tensor/tensor.hpp"

namespace dvs {
namespace {

Tensor random_tensor(vk::Context& c, Shape shape, DType dt, uint32_t seed, float offset = 0.f) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> u(0.f, 1.f);
  HostTensor h(shape, dt);
  for (int64_t i = 0; i < shape_numel(shape); ++i) {
    float v = offset + u(rng);
    if (dt == DType::f32) h.as<float>()[i] = v;
    else if (dt == DType::bf16) h.as<uint16_t>()[i] = f32_to_bf16(v);
    else h.as<uint16_t>()[i] = f32_to_f16(v);
  }
  return Tensor::upload(c, h);
}

class SplitNormTest : public test::GpuTest {
 protected:
  struct Result {
    std::vector<float> y;
    uint32_t dispatches = 0;
    uint64_t noted = 0;  // splits this call noted (all ops)
  };

  // make() builds fresh inputs and returns the output tensor and the op to record on them.
  using Op = std::function<void(vk::Recorder&)>;
  Result run(const std::function<Tensor(Op&)>& make, const std::string& limits) {
    Op op;
    Tensor y = make(op);
    Result r;
    {
      std::optional<test::ScopedLimits> scope;
      if (!limits.empty()) scope.emplace(ctx(), limits);
      const uint64_t noted = test::split_notes(ctx());
      ops::run_now(ctx(), [&](vk::Recorder& rec) {
        op(rec);
        r.dispatches = rec.dispatch_count();
      });
      r.noted = test::split_notes(ctx()) - noted;
    }
    r.y = y.download(ctx()).to_f32();
    return r;
  }

  void check(const std::function<Tensor(Op&)>& make, const std::string& limits) {
    SCOPED_TRACE("limits " + limits);
    Result plain = run(make, ""), split = run(make, limits);
    // Without DVS_LIMITS the plain call takes its usual dispatches; under a DVS_LIMITS profile it may split.
    if (ctx().caps().forced_limits.binding || ctx().caps().forced_limits.groups)
      EXPECT_GE(split.dispatches, plain.dispatches);
    else {
      EXPECT_GT(split.dispatches, plain.dispatches) << "the forced limits did not split the op";
      EXPECT_EQ(plain.noted, 0u) << "the unsplit op noted a split";
    }
    EXPECT_GT(split.noted, 0u) << "the split op did not note it (ctx.note_split)";
    ASSERT_EQ(plain.y.size(), split.y.size());
    EXPECT_EQ(std::memcmp(plain.y.data(), split.y.data(), plain.y.size() * 4), 0) << "split result differs";
  }
};

// [3 batches x 29 tokens, D] with a two-set modulation table (text: 7 tokens): chunks of a few rows start
// inside batches and inside the text part. D = 28 (vec4) and 29 (scalar), bf16 affine, both row mappings.
TEST_F(SplitNormTest, LayerNormModulationAcrossBatches) {
  for (const char* mapping : {"norm_row_per_invocation=on", "norm_row_per_invocation=off"})
    for (int64_t D : {28, 29}) {
      SCOPED_TRACE(std::string(mapping) + " D=" + std::to_string(D));
      ops::ScopedTuningOverride row_mapping(mapping);
      const int64_t B = 3, L = 29, W = 4 * D + 4;
      check(
          [&](Op& op) {
            Tensor x = random_tensor(ctx(), {B, L, D}, DType::f32, 1, 3.f);
            Tensor y = Tensor::empty(ctx(), {B, L, D}, DType::f32);
            Tensor w = random_tensor(ctx(), {D}, DType::bf16, 2), b = random_tensor(ctx(), {D}, DType::bf16, 3);
            ops::Modulation mod;
            mod.table = random_tensor(ctx(), {B, W}, DType::f32, 4);
            mod.seq_len = L;
            mod.split = 7;
            mod.shift_col[0] = 4;
            mod.scale_col[0] = 4 + D;
            mod.shift_col[1] = 4 + 2 * D;
            mod.scale_col[1] = 4 + 3 * D;
            op = [=](vk::Recorder& rec) { ops::layernorm(rec, x, y, w, b, 1e-5f, &mod); };
            return y;
          },
          "binding=1KiB");
    }
}

// Short sequences (7 batches of 3 tokens, text 1): a chunk of 10 rows spans up to 4 batches' table rows.
TEST_F(SplitNormTest, LayerNormModulationManyBatchesPerChunk) {
  const int64_t B = 7, L = 3, D = 28, W = 4 * D + 4;
  check(
      [&](Op& op) {
        Tensor x = random_tensor(ctx(), {B, L, D}, DType::f32, 17);
        Tensor y = Tensor::empty(ctx(), {B, L, D}, DType::f32);
        ops::Modulation mod;
        mod.table = random_tensor(ctx(), {B, W}, DType::f32, 18);
        mod.seq_len = L;
        mod.split = 1;
        mod.shift_col[0] = 4 + 3 * D;
        mod.scale_col[0] = 4 + 2 * D;
        mod.shift_col[1] = 4 + D;
        mod.scale_col[1] = 4;
        op = [=](vk::Recorder& rec) { ops::layernorm(rec, x, y, {}, {}, 1e-5f, &mod); };
        return y;
      },
      "binding=2KiB");
}

// No modulation, in place, more rows than 64x64 workgroups hold (workgroup per row): split by the grid.
TEST_F(SplitNormTest, LayerNormRowsByGrid) {
  ops::ScopedTuningOverride row_mapping("norm_row_per_invocation=off");
  check(
      [&](Op& op) {
        Tensor x = random_tensor(ctx(), {4099, 3}, DType::f32, 5);
        op = [=](vk::Recorder& rec) { ops::layernorm(rec, x, x, {}, {}, 1e-5f); };
        return x;
      },
      "groups=64");
}

// Fused QKV rows [41, 3*H*Dh + pad]: k heads normalised in place, rows chunked; the other columns untouched.
TEST_F(SplitNormTest, HeadLayerNormRowChunks) {
  for (int64_t Dh : {12, 7}) {
    SCOPED_TRACE("Dh=" + std::to_string(Dh));
    const int64_t H = 3, stride = 3 * H * Dh + 4;
    check(
        [&](Op& op) {
          Tensor x = random_tensor(ctx(), {41, stride}, DType::f32, 6, 2.f);
          Tensor w = random_tensor(ctx(), {Dh}, DType::f32, 7), b = random_tensor(ctx(), {Dh}, DType::f32, 8);
          op = [=](vk::Recorder& rec) { ops::head_layernorm(rec, x, x, H, Dh, H * Dh, w, b); };
          return x;
        },
        "binding=2KiB");  // rows of 268 B need 4-row (aligned) chunks
  }
}

TEST_F(SplitNormTest, RmsNormRowChunks) {
  for (int64_t D : {45, 36}) {
    check(
        [&](Op& op) {
          Tensor x = random_tensor(ctx(), {53, D}, DType::f32, 9);
          Tensor y = Tensor::empty(ctx(), {53, D}, DType::f32);
          Tensor w = random_tensor(ctx(), {D}, DType::f16, 10);
          op = [=](vk::Recorder& rec) { ops::rmsnorm(rec, x, y, w); };
          return y;
        },
        "binding=1KiB");
  }
}

// [2, 8, 5, 7] in 2 groups: groups of 560 B, 16 planes of 140 B; a 1 KiB binding splits the statistics into
// single groups and the apply pass into 7-plane chunks (starting unaligned: element offsets). With SiLU and
// bf16 affine; and [2, 8, 4, 9] (vec4 apply).
TEST_F(SplitNormTest, GroupNormChunks) {
  for (Shape shape : {Shape{2, 8, 5, 7}, Shape{2, 8, 4, 9}}) {
    SCOPED_TRACE(shape_str(shape));
    check(
        [&](Op& op) {
          Tensor x = random_tensor(ctx(), shape, DType::f32, 11, 5.f);
          Tensor y = Tensor::empty(ctx(), shape, DType::f32);
          Tensor g = random_tensor(ctx(), {8}, DType::bf16, 12), b = random_tensor(ctx(), {8}, DType::bf16, 13);
          Tensor scratch = Tensor::empty(ctx(), {ops::groupnorm_scratch_elems(shape, 2)}, DType::f32);
          op = [=](vk::Recorder& rec) { ops::groupnorm(rec, x, y, 2, g, b, 1e-6f, true, scratch); };
          return y;
        },
        "binding=1KiB");
  }
}

// 70 planes: more than 64 workgroups along y, split by the grid (no affine).
TEST_F(SplitNormTest, GroupNormPlanesByGrid) {
  const Shape shape{1, 70, 3, 3};
  check(
      [&](Op& op) {
        Tensor x = random_tensor(ctx(), shape, DType::f32, 14);
        Tensor scratch = Tensor::empty(ctx(), {ops::groupnorm_scratch_elems(shape, 10)}, DType::f32);
        op = [=](vk::Recorder& rec) { ops::groupnorm(rec, x, x, 10, {}, {}, 1e-6f, false, scratch); };
        return x;
      },
      "groups=64");
}

// Planes of 66,001 elements need 65 workgroups of 1024 elements: over 64, each plane's apply pass is split
// into runs (the second plane's runs start unaligned: element offsets). The statistics must fit one binding
// here (a group larger than one binding is reduce_segments' own split), so tiny DVS_LIMITS skip this.
TEST_F(SplitNormTest, GroupNormRunsInsidePlanes) {
  const Shape shape{1, 2, 66001};
  if (ctx().caps().max_storage_buffer_range < uint64_t(shape_numel(shape)) * 4)
    GTEST_SKIP() << "x exceeds one binding under the forced limits";
  check(
      [&](Op& op) {
        Tensor x = random_tensor(ctx(), shape, DType::f32, 19, -2.f);
        Tensor y = Tensor::empty(ctx(), shape, DType::f32);
        Tensor g = random_tensor(ctx(), {2}, DType::f32, 20), b = random_tensor(ctx(), {2}, DType::f32, 21);
        Tensor scratch = Tensor::empty(ctx(), {ops::groupnorm_scratch_elems(shape, 1)}, DType::f32);
        op = [=](vk::Recorder& rec) { ops::groupnorm(rec, x, y, 1, g, b, 1e-6f, false, scratch); };
        return y;
      },
      "groups=64");
}

// A row wider than one binding would need split statistics (never at model sizes: rows of at most 16 KiB
// against bindings of at least 128 MiB): a clear error, not a bad dispatch.
TEST_F(SplitNormTest, RowWiderThanBindingIsAnError) {
  Tensor x = random_tensor(ctx(), {2, 300}, DType::f32, 15);
  test::ScopedLimits l(ctx(), "binding=1KiB");
  try {
    Tensor w = random_tensor(ctx(), {300}, DType::f32, 16);
    ops::run_now(ctx(), [&](vk::Recorder& rec) { ops::rmsnorm(rec, x, x, w); });
    ADD_FAILURE() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("does not fit one binding"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace dvs
