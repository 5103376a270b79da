// The convolution's input repack (ops_conv_pack.hpp) byte for byte: the transpose through shared memory
// (DeviceTuning::conv_pack_tiled, conv_pack_input_tiled.comp) must write exactly what the invocation-per-vec4 repack
// (conv_pack_input.comp) writes, every byte of the packed chunk: the zero channels up to CP and the zero pixel
// included, which the convolutions' results cannot show (their packed weights are zero there, so a value read from
// the wrong channel would vanish unless it were a NaN). The packed buffer starts filled with NaNs, so a byte either
// kernel leaves unwritten differs too. Cases: every time mode (causal prefix, the upsampler's odd and even frame
// maps, the cache), a chunk of input channels starting past 0, source rows and columns inside the image, the
// shifted-GEMM convolution's zero-padded grid and its x2-upsampled one, rows of more than one 64-column tile, fp16
// and f32, whole and under texel limits that split the repack into channel groups: of 3 (all but the last merge their
// channels into vec4s others wrote, which only the per-vec4 kernel does, so both kernels run in one repack) and of 4
// (this kernel's channel tiles starting past channel 0).
#include <gtest/gtest.h>

#include <cstring>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include "support/gpu.hpp"
#include "support/scoped_limits.hpp"
#include "support/stored_values.hpp"
#include "tensor/dispatch.hpp"
#include "tensor/kernel_tuning.hpp"
#include "tensor/ops_conv_pack.hpp"
#include "vk/pipeline.hpp"

namespace dvs {
namespace {

using ops::conv::PackGrid;

class ConvRepackOps : public test::GpuTest {};

struct RepackCase {
  std::string name;
  uint32_t time_mode;
  int64_t prefix, nframes;     // the causal prefix; packed frames from tp0 = 0
  int64_t c0, cc;              // input channels [c0, c0 + cc)
  int64_t r0, rows, col0, wc;  // source rows and columns (of the x2 upsampling where grid.up is 2)
  PackGrid grid;
};

TEST_F(ConvRepackOps, TiledWritesTheSameBytesAsThePerVec4Repack) {
  vk::Context& c = ctx();
  const int64_t B = 2, C = 37, F = 3, H = 5, W = 67;
  const Tensor x = test::random_stored(c, {B, C, F, H, W}, 1, 1.f, DType::f32);
  const Tensor cache = test::random_stored(c, {B, C, 2, H, W}, 2, 1.f, DType::f32);
  const RepackCase cases[] = {
      {"causal prefix, whole", 0, 2, F + 2, 0, C, 0, H, 0, W, {}},
      {"cache, channels 8..27, rows 1..3, columns 2..61", 3, 2, F + 2, 8, 20, 1, 3, 2, 60, {}},
      {"upsampler, odd frames", 1, 0, 2 * F - 1, 0, C, 0, H, 0, W, {}},
      {"cache, padded grid", 3, 2, F + 2, 0, C, 0, H, 0, W, {1, H + 2, 1, W + 2, 1}},
      {"causal prefix, padded grid of rows 2..4", 0, 2, F + 2, 0, C, 2, 3, 0, W, {1, 4, 1, W + 2, 1}},
      {"upsampler, even frames, x2 grid of rows 3..8", 2, 0, 2 * F, 0, C, 3, 6, 0, 2 * W, {1, 8, 1, 2 * W + 2, 2}},
  };
  for (const bool f16 : {true, false})
    for (const char* limits : {static_cast<const char*>(nullptr), "texels=3072", "texels=4096"})
      for (const RepackCase& k : cases) {
        const std::string where = k.name + (f16 ? ", fp16" : ", f32") + (limits ? std::string(", ") + limits : "");
        ops::conv::ConvJob j;
        j.b = B, j.cin = C, j.frames = F, j.h = H, j.w = W, j.prefix = k.prefix, j.time_mode = k.time_mode;
        j.cache = k.time_mode == 3 ? &cache : nullptr;
        const int64_t cpc = (k.cc + 7) / 8 * 8;
        const int64_t rows_p = k.grid.rows_p ? k.grid.rows_p : k.rows, cols_p = k.grid.cols_p ? k.grid.cols_p : k.wc;
        const int64_t words = ((k.nframes * rows_p * cols_p + 1) * cpc * (f16 ? 2 : 4) + 3) / 4;
        // The packed chunk is one binding (callers cut chunks that fit): not under DVS_LIMITS' smaller ones.
        if (uint64_t(words) * 4 > c.caps().max_storage_buffer_range) {
          std::cout << "[ SKIPPED  ] " << where << ": the packed chunk exceeds the binding limit in force\n";
          continue;
        }
        auto packed_by = [&](const char* tiled) {
          const Tensor out = Tensor::upload(c, HostTensor::from_f32({words}, std::vector<float>(size_t(words), NAN)));
          ops::ScopedTuningOverride t(std::string("conv_pack_tiled=") + tiled);
          std::unique_ptr<test::ScopedLimits> scope;
          if (limits) scope = std::make_unique<test::ScopedLimits>(c, limits);
          const ops::conv::ConvLimits l = ops::conv::conv_limits(c.caps());
          uint32_t dispatches = 0;
          ops::run_now(c, [&](vk::Recorder& rec) {
            ops::conv::pack_input(rec, "repack test", j, x, l, 1, k.c0, k.cc, cpc, 0, k.nframes, k.r0, k.rows, k.col0,
                                  k.wc, f16, out.buffer(), 4, k.grid);
            dispatches = rec.dispatch_count();
          });
          // Under the limits the repack ran in channel groups (whole: one dispatch, unless DVS_LIMITS forces some).
          if (limits) EXPECT_GT(dispatches, 1u) << where;
          else if (!c.caps().forced_limits.any()) EXPECT_EQ(dispatches, 1u) << where;
          const HostTensor h = out.download(c);
          std::vector<uint32_t> bits(static_cast<size_t>(words));
          std::memcpy(bits.data(), h.data.data(), bits.size() * 4);
          return bits;
        };
        const std::vector<uint32_t> tiled = packed_by("on"), per_vec4 = packed_by("off");
        size_t differ = 0, unwritten = 0;
        for (size_t i = 0; i < tiled.size(); ++i) {
          differ += tiled[i] != per_vec4[i];
          unwritten += per_vec4[i] == 0x7fc00000u;
        }
        EXPECT_EQ(differ, 0u) << where << ": words of the packed chunk that differ";
        EXPECT_EQ(unwritten, 0u) << where << ": words the per-vec4 repack left unwritten";
      }
  bool made = false;
  c.pipelines().for_each([&](const vk::Pipeline& pl) { made = made || pl.name == "nn/conv_pack_input_tiled"; });
  EXPECT_TRUE(made) << "the transposing repack never ran";
}

}  // namespace
}  // namespace dvs
