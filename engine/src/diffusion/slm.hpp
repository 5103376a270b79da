// Stochastic Latent Modulation (paper §4.4 / App. D; docs/design.md §5.5; official code: docs/design.md §6.6).
//
// Three steps:
//  1. compute_slm_masks: the renderer's pixel mask [Fp, H, W] (f32, 1 = visible) and optional depth are reduced
//     over each latent cell's footprint ON THE GPU (shaders/diffusion/slm_footprint.comp), the small per-cell
//     statistics [Fl, H/8, W/8] are downloaded and thresholded on the host into cell masks (bookkeeping).
//  2. make_slm_plan: builds, on the host, the index lists of one latent shape and scope (targets, source pool,
//     per-frame / per-channel pool segments) and uploads them once. Masks stay fixed across rounds, so a plan
//     is built once and replayed.
//  3. apply_slm: records one dispatch (shaders/diffusion/slm_sample.comp) that sets every target element of a
//     latent [Fl, C, Hl, Wl] (f32) to a source element drawn uniformly with replacement from its pool with
//     the Philox generator: target i (in ascending element order) uses draw element base + i of
//     (seed, stream), philox::below(seed, stream, base + i, pool size). A seed reproduces bit-identical results
//     on every device.
//
// Presets:
//  - paper: footprint = 4 pixel frames x 8x8 pixels (latent frame 0: pixel frame 0 alone; frame j >= 1: pixel
//    frames 4j-3 .. 4j). M = 1 (occluded) where the hole fraction, mean of 1 - clamp(mask, 0, 1), exceeds
//    hole_threshold (default 0: any hole). D = 1 (background) where the mean over the footprint of the
//    per-frame normalised disparity d / max_frame(d) is below background_threshold (disparity = 1/z for metric
//    depth; non-positive values count as 0). Source S = (1 - M)·D; when S is empty the source falls back to
//    1 - M; without depth (or with use_background off) D = 1. Both x0 and ε use target M and source S.
//  - official: V = downsize_mask(mask) (temporal pair means, three zero-pad-right/bottom 3x3 stride-2 average
//    pools, so the last latent row and column never reach 1). x0: target P = (V < 1), source ~P. ε: target
//    C = (V <= τ), source ~C, with τ = unique(V)[-treshold_idx] (sorted ascending, Python indexing; the
//    config's -1 gives the second-smallest value). Depth is ignored. Computed in fp32 (the authors resize in
//    bf16, so τ and the P/C borders can differ where their bf16 rounding moves a value).
//    Not included: the authors' area resize from the render size (576x1024) to the diffusion size; the
//    caller passes the mask at the diffusion resolution.
//
// Scopes: global (pool = all source cells x all channels, as the official code and the paper's 5-D masks),
// frame (source cells of the target's latent frame, any channel), frame_channel (same frame and channel).
// A frame without source cells falls back to the global pool (frame scope) or to the same channel of every
// frame (frame_channel); SlmIndexPlan::fallback_segments counts those.
#pragma once
#include <cstdint>
#include <string>
#include <vector>

#include "io/host_tensor.hpp"
#include "tensor/ops_random.hpp"
#include "tensor/tensor.hpp"
#include "vk/context.hpp"
#include "vk/recorder.hpp"

namespace dvs::diffusion {

struct SlmOptions {
  enum class Preset { paper, official };
  enum class Scope { global, frame, frame_channel };
  Preset preset = Preset::paper;
  float hole_threshold = 0.0f;        // paper: occluded where hole fraction > this
  float background_threshold = 0.3f;  // paper: background where mean normalised disparity < this
  bool use_background = true;         // paper: source = visible ∧ background (false: visible only)
  int treshold_idx = -1;              // official: τ = unique(V)[-treshold_idx] (the authors' spelling)
  Scope scope = Scope::global;
  uint64_t seed = 0;                  // used by slm_streams(); apply_slm takes explicit streams
};

// Cell masks at latent resolution, each [frames · height · width] in (f, h, w) order, 1 = set.
struct SlmMasks {
  int frames = 0, height = 0, width = 0;
  // The GPU reductions: paper: [0] hole fraction, [1] mean normalised disparity (0 without depth);
  // official: [0] V. Kept for inspection and tests.
  std::vector<float> hole_fraction, background_mean, visibility;
  std::vector<uint8_t> x0_target, x0_source;    // paper: M, S; official: P, ~P
  std::vector<uint8_t> eps_target, eps_source;  // paper: M, S; official: C, ~C
  bool source_fell_back = false;  // paper: (1 - M)·D was empty, the source is 1 - M
  float tau = 0.0f;               // official: the V threshold of C
  int64_t cells() const { return int64_t(frames) * height * width; }
};

// Pixel mask [Fp, H, W] f32 with Fp = 4·(latent_frames - 1) + 1 and H, W multiples of 8; depth (optional)
// [Fp, H, W] f32, metric depth z when depth_is_metric, else disparity. Throws dvs::Error when no latent cell
// is visible (nothing to sample from) or when τ's index is out of range.
SlmMasks compute_slm_masks(vk::Context& ctx, const HostTensor& pixel_mask, const HostTensor* depth,
                           bool depth_is_metric, int latent_frames, const SlmOptions& options);
// The same from device tensors (the renderer's outputs, [Fp, H, W] f32), without a host round trip.
SlmMasks compute_slm_masks(vk::Context& ctx, const Tensor& pixel_mask, const Tensor* depth, bool depth_is_metric,
                           int latent_frames, const SlmOptions& options);

// Index lists of one (target, source) pair for a latent [F, C, H, W]. Empty `targets` (no target cell):
// apply_slm records nothing.
struct SlmIndexPlan {
  Tensor targets;   // i32 [T, 2]: (flat element index, segment), elements ascending
  Tensor segments;  // i32 [S, 2]: (offset into pool, length >= 1)
  Tensor pool;      // i32 [P]: flat element indices of the source elements
  int64_t n_targets = 0, n_pool = 0;
  int64_t latent_numel = 0;   // F·C·H·W of the latent it was built for
  int fallback_segments = 0;  // segments whose own pool was empty and that use the wider one
};

struct SlmPlan {
  Shape latent_shape;  // [F, C, H, W]
  SlmIndexPlan x0, eps;
};

// Host-side index building for one target/source pair; exposed for tests. `channels` = C.
SlmIndexPlan make_slm_index_plan(vk::Context& ctx, const std::vector<uint8_t>& target,
                                 const std::vector<uint8_t>& source, int frames, int height, int width,
                                 int channels, SlmOptions::Scope scope, const std::string& what);
SlmPlan make_slm_plan(vk::Context& ctx, const SlmMasks& masks, int channels, SlmOptions::Scope scope);

// Records the modulation of `latent` ([F, C, H, W] or [1, F, C, H, W], f32) in place.
void apply_slm(vk::Recorder& rec, const Tensor& latent, const SlmIndexPlan& plan, const ops::RandomStream& rs);

// The streams the pipeline uses: x0 and ε draw from different Philox streams of the same seed; `round`
// (the official code modulates three times) moves the draw window so rounds are independent.
constexpr uint32_t kSlmStreamX0 = 0x534c4d30u;   // "SLM0"
constexpr uint32_t kSlmStreamEps = 0x534c4d31u;  // "SLM1"
ops::RandomStream slm_stream(uint64_t seed, bool eps, int round, int64_t latent_numel);

// The x0 target cells (official: P = positions_to_replace = V < 1; paper: M) as an f32 latent [F, C, h, w]
// (1 = set, the same in every channel): the positions the official dynamic CFG guides with its per-step scale.
Tensor positions_to_replace(vk::Context& ctx, const SlmMasks& masks, int channels);

// Convenience: x0 and ε modulated with their own streams of options.seed, round `round`.
void apply_slm(vk::Recorder& rec, const Tensor& x0, const Tensor& eps, const SlmPlan& plan, uint64_t seed,
               int round = 0);

}  // namespace dvs::diffusion
