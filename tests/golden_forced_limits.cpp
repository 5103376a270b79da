// The golden end-to-end chain (PipelineE2e.ChainedFromTheVideo: encode the video, invert, K-RNR, sample,
// decode) a second time under the CI profile's forced limits, against the same goldens at the same
// tolerances, and proof that those limits really take the split paths: every op of kForced below must be in
// ctx().splits() afterwards. Without forced limits the same chain must note no split at all (the fast path).
// Ops whose split the pack's sizes cannot reach under this profile are listed in kNotReached with the
// tests/test_split_*.cpp suite that forces them instead.
#include <gtest/gtest.h>

#include <iostream>
#include <string>

#include "support/pipeline_e2e.hpp"
#include "support/scoped_limits.hpp"

namespace dvs {
namespace {

// The CI profile (tests/run_with_forced_limits.sh sets the same DVS_LIMITS for the whole suite).
constexpr const char* kCiProfile = "binding=64KiB,texels=16384,alloc=4MiB,groups=64";

struct Forced {
  const char* op;
  const char* why;  // which limit of kCiProfile forces it at the pack's sizes
};

// Derived by running the chain under kCiProfile and under each of its four limits alone (the splits() map the
// test prints). The pack: video [1, 3, 9, 64, 64], VAE channels 8/16/16/16 (4 groups), latent [4, 3, 8, 8];
// a VAE activation [1, 8, 9, 64, 64] is 1.2 MB, 18x one 64 KiB binding.
const Forced kForced[] = {
    {"causal_conv3d", "binding=64KiB < the VAE's [1, 8..16, F, 64..32, ..] activations (also texels=16384: the "
                      "repacked input's RGBA view; groups=64: the GEMM grid over 9 x 64 x 64 output pixels)"},
    {"conv cache", "binding=64KiB < the causal conv's cached frames of a whole [B*C, frames, H*W] activation"},
    {"conv2d", "binding=64KiB < the per-frame 2-D down/up-sampling convs' [F, C, H, W] inputs (also texels, groups)"},
    {"groupnorm", "binding=64KiB < the VAE's [1, C, F, H, W] activations (statistics and apply in plane chunks)"},
    {"reduce", "binding=64KiB < the groupnorm statistics' input (reduce_segments windows over one segment)"},
    {"silu", "binding=64KiB < the VAE activations' element count (flat chunks)"},
    {"add", "binding=64KiB < the VAE resnet residual sums (broadcast chunks)"},
    {"scale_shift", "binding=64KiB < the VAE's scaled / shifted activations (broadcast chunks)"},
    {"avgpool_time_pairs", "binding=64KiB < the encoder's temporal downsampling input (plane chunks)"},
    {"upsample_nearest", "binding=64KiB < the decoder's spatial upsampling output"},
    {"upsample2x", "binding=64KiB < the decoder's 2x upsampling output (also groups=64: its row grid)"},
    {"permute", "binding=64KiB < the 64x64 video-sized tensors the chain permutes (2 calls)"},
    {"nonfinite", "binding=64KiB < the video-sized tensors checked for NaN / Inf (ranges of one binding, 2 calls)"},
};

// Ops with a split path that the pack's sizes do not reach under kCiProfile: the pack's transformer is 2 heads
// x 16 wide over 48 + 8 tokens (its largest activation 7 KiB) and its latent 768 floats; alloc=4MiB: no arena
// exceeds 4 MiB. Their splits are shown (forced lower, odd sizes) in these suites:
const Forced kNotReached[] = {
    {"linear", "SplitLinearTest (test_split_linear.cpp)"},
    {"layernorm / head_layernorm / rmsnorm", "SplitNormTest (test_split_norm.cpp)"},
    {"attention", "SplitAttentionTest (test_split_attention.cpp)"},
    {"rope", "SplitPosition (test_split_position.cpp)"},
    {"guided step / krnr / adain", "SplitDiffusion (test_split_diffusion.cpp)"},
    {"cast / unary / random fills", "SplitElementwise (test_split_elementwise.cpp)"},
    {"concat / split / patchify / unpatchify / gather rows", "SplitLayout (test_split_layout.cpp)"},
    {"arena blocks", "GpuTest.ArenaSpansBlocksUnderTheAllocationLimit, ArenaModels (test_vk_arena_blocks.cpp)"},
    {"nonfinite (storage fallback)", "texels=16384 alone: the frames' RGBA view; under the whole profile the "
                                     "64 KiB ranges fit a texel view"},
};

void print_splits(const std::string& title, const std::map<std::string, uint64_t>& splits) {
  std::cout << title << " (" << splits.size() << " ops):\n";
  for (const auto& [op, n] : splits) std::cout << "  " << op << ": " << n << " calls\n";
}

class ForcedLimits : public e2e::PipelineE2e {};

TEST_F(ForcedLimits, ChainSplitsEveryListedOpAndMatchesTheGoldens) {
  test::ScopedLimits limits(ctx(), kCiProfile);
  ctx().reset_splits();
  chained_from_the_video();
  const auto splits = ctx().splits();
  print_splits("splits under " + std::string(kCiProfile), splits);
  for (const Forced& f : kForced) EXPECT_TRUE(splits.count(f.op)) << f.op << " did not split (" << f.why << ")";
  for (const Forced& f : kNotReached) std::cout << "  not reached at the pack's sizes: " << f.op << " -> " << f.why << "\n";
}

TEST_F(ForcedLimits, ChainWithoutForcedLimitsTakesNoSplit) {
  if (ctx().caps().forced_limits.any()) GTEST_SKIP() << "DVS_LIMITS forces limits for the whole process";
  ctx().reset_splits();
  chained_from_the_video();
  print_splits("splits without forced limits", ctx().splits());
  EXPECT_TRUE(ctx().splits().empty()) << "the unsplit fast path noted a split";
}

}  // namespace
}  // namespace dvs
