#include "diffusion/slm.hpp"

#include <algorithm>
#include <cmath>

#include "dvs/error.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"

namespace dvs::diffusion {
namespace {

struct FootprintPush {
  uint32_t latent_frames, lh, lw, height, width, has_depth, metric;
  uint32_t first_latent, end_latent, pixel_frame0;  // this dispatch's latent frames; its window's first pixel frame
};
struct FrameMaxPush {
  uint32_t frames, pixels, metric, first_frame;
};
struct SamplePush {
  uint32_t n_targets, seed_lo, seed_hi, stream, base_lo, base_hi;
};

// [Fp, H, W] or [Fp, 1, H, W] f32 -> (Fp, H, W).
void pixel_dims(const char* what, const HostTensor& t, int64_t& fp, int64_t& h, int64_t& w) {
  if (t.dtype != DType::f32) throw Error(std::string("SLM: the ") + what + " must be f32, got " + dtype_name(t.dtype));
  if (t.shape.size() == 3) {
    fp = t.shape[0], h = t.shape[1], w = t.shape[2];
  } else if (t.shape.size() == 4 && t.shape[1] == 1) {
    fp = t.shape[0], h = t.shape[2], w = t.shape[3];
  } else {
    throw Error(std::string("SLM: the ") + what + " must be [frames, height, width], got " + shape_str(t.shape));
  }
}

std::string count_str(const std::vector<uint8_t>& m) {
  return std::to_string(std::count(m.begin(), m.end(), uint8_t(1))) + " of " + std::to_string(m.size());
}

Tensor upload_i32(vk::Context& ctx, const std::vector<int32_t>& v, Shape shape, const std::string& what) {
  HostTensor h(std::move(shape), DType::i32);
  std::copy(v.begin(), v.end(), h.as<int32_t>());
  return Tensor::upload(ctx, h, what);
}

}  // namespace

SlmMasks compute_slm_masks(vk::Context& ctx, const HostTensor& pixel_mask, const HostTensor* depth,
                           bool depth_is_metric, int latent_frames, const SlmOptions& options) {
  int64_t fp = 0, h = 0, w = 0;
  pixel_dims("pixel mask", pixel_mask, fp, h, w);
  const Tensor mask_t = Tensor::upload(ctx, pixel_mask, "slm pixel mask").reshape({fp, h, w});
  const bool with_depth = options.preset == SlmOptions::Preset::paper && options.use_background && depth != nullptr;
  Tensor depth_t;
  if (with_depth) {
    int64_t dfp = 0, dh = 0, dw = 0;
    pixel_dims("depth", *depth, dfp, dh, dw);
    depth_t = Tensor::upload(ctx, *depth, "slm depth").reshape({dfp, dh, dw});
  }
  return compute_slm_masks(ctx, mask_t, with_depth ? &depth_t : nullptr, depth_is_metric, latent_frames, options);
}

SlmMasks compute_slm_masks(vk::Context& ctx, const Tensor& pixel_mask, const Tensor* depth, bool depth_is_metric,
                           int latent_frames, const SlmOptions& options) {
  if (pixel_mask.dtype() != DType::f32 || pixel_mask.rank() != 3)
    throw Error("SLM: the pixel mask must be f32 [frames, height, width], got " + pixel_mask.describe());
  const int64_t fp = pixel_mask.shape()[0], h = pixel_mask.shape()[1], w = pixel_mask.shape()[2];
  if (latent_frames < 1 || fp != 4 * int64_t(latent_frames - 1) + 1)
    throw Error("SLM: a pixel mask of " + std::to_string(fp) + " frames does not give " +
                std::to_string(latent_frames) + " latent frames (needs 4·(F - 1) + 1 pixel frames)");
  if (h < 8 || w < 8 || h % 8 != 0 || w % 8 != 0)
    throw Error("SLM: the pixel mask size " + std::to_string(h) + "x" + std::to_string(w) +
                " must be a multiple of 8 (the VAE's spatial factor)");
  const bool paper = options.preset == SlmOptions::Preset::paper;
  const bool with_depth = paper && options.use_background && depth != nullptr;
  if (with_depth && (depth->dtype() != DType::f32 || depth->shape() != pixel_mask.shape()))
    throw Error("SLM: depth " + depth->describe() + " does not match the pixel mask " + pixel_mask.describe());

  SlmMasks m;
  m.frames = latent_frames;
  m.height = int(h / 8);
  m.width = int(w / 8);
  const int64_t cells = m.cells();

  // GPU: per-frame disparity maxima (paper with depth), then the footprint reductions.
  const Tensor& mask_t = pixel_mask;
  const Tensor& depth_t = with_depth ? *depth : pixel_mask;  // unread without depth
  const Tensor frame_max = Tensor::zeros(ctx, {fp}, DType::f32, "slm frame max");
  const Tensor stats = Tensor::empty(ctx, {2, cells}, DType::f32, "slm footprint stats");
  // Pixel frames are bound in windows of whole frames that fit one binding (a frame's bytes are a multiple of
  // 256: h, w are multiples of 8), so a clip larger than one binding splits over frames; frame_max and the
  // stats (1/64 and 1/128 of a mask) stay bound whole.
  const vk::DeviceCaps& caps = ctx.caps();
  const uint64_t frame_bytes = uint64_t(h * w) * 4;
  const int64_t frames_per_window = int64_t(caps.max_storage_buffer_range / frame_bytes);
  if (frames_per_window < 4)
    throw Error("SLM: four " + std::to_string(h) + "x" + std::to_string(w) + " mask frames (one latent frame's "
                "footprint) exceed one storage binding (maxStorageBufferRange " +
                vk::format_bytes(caps.max_storage_buffer_range) + ")");
  auto frames_view = [&](const Tensor& t, int64_t first, int64_t count) {
    return t.buffer().sub(VkDeviceSize(first) * frame_bytes, VkDeviceSize(count) * frame_bytes);
  };
  ops::run_now(ctx, [&](vk::Recorder& rec) {
    if (fp > frames_per_window) rec.context().note_split("slm");
    if (with_depth) {
      ops::for_each_chunk(fp, frames_per_window, [&](int64_t f0, int64_t n) {
        FrameMaxPush p{uint32_t(n), uint32_t(h * w), depth_is_metric ? 1u : 0u, uint32_t(f0)};
        rec.dispatch(rec.context().pipelines().get("diffusion/slm_frame_max"),
                     {frames_view(depth_t, f0, n), frame_max.buffer()}, &p, sizeof p, uint32_t(n), 1, 1,
                     "slm_frame_max");
      });
    }
    const uint32_t spec[] = {paper ? 0u : 1u};
    // Latent frame j >= 1 reads pixel frames 4j-3 .. 4j: (frames_per_window - 1) / 4 of them fit a window
    // with room for frame 0 in the first; at least one (four frames fit, checked above).
    const int64_t latent_per_window = std::max<int64_t>(1, (frames_per_window - 1) / 4);
    ops::for_each_chunk(latent_frames, latent_per_window, [&](int64_t k0, int64_t kn) {
      const int64_t pf0 = k0 == 0 ? 0 : 4 * k0 - 3, pf1 = 4 * (k0 + kn - 1) + 1;
      FootprintPush p{uint32_t(latent_frames), uint32_t(m.height), uint32_t(m.width), uint32_t(h), uint32_t(w),
                      with_depth ? 1u : 0u, depth_is_metric ? 1u : 0u, uint32_t(k0), uint32_t(k0 + kn), uint32_t(pf0)};
      const ops::Grid g = ops::grid_1d(rec.context().caps(), kn * m.height * m.width, 64);
      rec.dispatch(rec.context().pipelines().get("diffusion/slm_footprint", spec),
                   {frames_view(mask_t, pf0, pf1 - pf0), frames_view(depth_t, pf0, pf1 - pf0), frame_max.buffer(),
                    stats.buffer()},
                   &p, sizeof p, g.x, g.y, g.z, "slm_footprint");
    });
  });
  const std::vector<float> s = stats.download(ctx).to_f32();

  // Host: thresholds and complements of the small per-cell statistics.
  if (paper) {
    m.hole_fraction.assign(s.begin(), s.begin() + cells);
    m.background_mean.assign(s.begin() + cells, s.end());
    std::vector<uint8_t> occluded(cells), source(cells);
    int64_t visible = 0, picked = 0;
    for (int64_t i = 0; i < cells; ++i) {
      occluded[i] = m.hole_fraction[i] > options.hole_threshold ? 1 : 0;
      visible += 1 - occluded[i];
      const bool background = !with_depth || m.background_mean[i] < options.background_threshold;
      source[i] = !occluded[i] && background ? 1 : 0;
      picked += source[i];
    }
    if (visible == 0)
      throw Error("SLM: no latent cell is visible in the render (every " + std::to_string(h) + "x" + std::to_string(w) +
                  " footprint has holes above the threshold " + std::to_string(options.hole_threshold) +
                  "), so there is nothing to fill the occluded regions from; check the camera trajectory and depth");
    if (picked == 0) {
      m.source_fell_back = true;
      for (int64_t i = 0; i < cells; ++i) source[i] = 1 - occluded[i];
    }
    m.x0_target = occluded;
    m.eps_target = occluded;
    m.x0_source = source;
    m.eps_source = source;
  } else {
    m.visibility.assign(s.begin(), s.begin() + cells);
    std::vector<float> uniq = m.visibility;
    std::sort(uniq.begin(), uniq.end());
    uniq.erase(std::unique(uniq.begin(), uniq.end()), uniq.end());
    int64_t k = -int64_t(options.treshold_idx);
    if (k < 0) k += int64_t(uniq.size());
    if (k < 0 || k >= int64_t(uniq.size()))
      throw Error("SLM: treshold_idx " + std::to_string(options.treshold_idx) + " is out of range: the latent mask has " +
                  std::to_string(uniq.size()) + " distinct values");
    m.tau = uniq[size_t(k)];
    m.x0_target.resize(cells);
    m.x0_source.resize(cells);
    m.eps_target.resize(cells);
    m.eps_source.resize(cells);
    for (int64_t i = 0; i < cells; ++i) {
      const float v = m.visibility[i];
      m.x0_target[i] = v < 1.0f ? 1 : 0;
      m.x0_source[i] = 1 - m.x0_target[i];
      m.eps_target[i] = v <= m.tau ? 1 : 0;
      m.eps_source[i] = 1 - m.eps_target[i];
    }
    if (std::count(m.x0_source.begin(), m.x0_source.end(), uint8_t(1)) == 0)
      throw Error("SLM: no latent cell is fully visible (V = 1 nowhere; " + count_str(m.x0_target) +
                  " cells occluded), so there is nothing to fill the occluded regions from; check the camera "
                  "trajectory and depth");
    if (std::count(m.eps_source.begin(), m.eps_source.end(), uint8_t(1)) == 0)
      throw Error("SLM: every latent cell has V <= tau = " + std::to_string(m.tau) + "; nothing to sample ε from");
  }
  return m;
}

SlmIndexPlan make_slm_index_plan(vk::Context& ctx, const std::vector<uint8_t>& target,
                                 const std::vector<uint8_t>& source, int frames, int height, int width,
                                 int channels, SlmOptions::Scope scope, const std::string& what) {
  const int64_t hw = int64_t(height) * width, cells = frames * hw;
  if (int64_t(target.size()) != cells || int64_t(source.size()) != cells || channels < 1)
    throw Error("internal: make_slm_index_plan: masks of " + std::to_string(target.size()) + "/" +
                std::to_string(source.size()) + " cells for a " + std::to_string(frames) + "x" +
                std::to_string(height) + "x" + std::to_string(width) + " grid");
  if (cells * channels > int64_t(INT32_MAX)) throw Error("internal: make_slm_index_plan: latent too large for i32");
  for (int64_t i = 0; i < cells; ++i)
    if (target[i] && source[i]) throw Error("internal: make_slm_index_plan: a cell is both target and source");

  // Source cells per frame (cell order), and their counts.
  std::vector<std::vector<int32_t>> src_cells(frames);
  for (int f = 0; f < frames; ++f)
    for (int64_t k = 0; k < hw; ++k)
      if (source[f * hw + k]) src_cells[f].push_back(int32_t(k));
  int64_t n_src_cells = 0;
  for (const auto& v : src_cells) n_src_cells += int64_t(v.size());

  SlmIndexPlan plan;
  plan.latent_numel = cells * channels;
  std::vector<int32_t> targets;
  for (int f = 0; f < frames; ++f)
    for (int c = 0; c < channels; ++c)
      for (int64_t k = 0; k < hw; ++k)
        if (target[f * hw + k]) {
          const int32_t seg = scope == SlmOptions::Scope::global ? 0
                              : scope == SlmOptions::Scope::frame ? f
                                                                  : f * channels + c;
          targets.push_back(int32_t((int64_t(f) * channels + c) * hw + k));
          targets.push_back(seg);
        }
  plan.n_targets = int64_t(targets.size() / 2);
  if (plan.n_targets == 0) return plan;
  if (n_src_cells == 0)
    throw Error("SLM: " + what + " has " + std::to_string(plan.n_targets) + " target elements but no source cell");

  std::vector<int32_t> pool, segments;
  auto element = [&](int f, int c, int32_t k) { return int32_t((int64_t(f) * channels + c) * hw + k); };
  if (scope == SlmOptions::Scope::frame_channel) {
    // Pool ordered (channel, frame, cell): segment (f, c) is contiguous, and so is "channel c, any frame".
    for (int c = 0; c < channels; ++c) {
      const int32_t channel_off = int32_t(pool.size());
      std::vector<int32_t> frame_off(frames);
      for (int f = 0; f < frames; ++f) {
        frame_off[f] = int32_t(pool.size());
        for (int32_t k : src_cells[f]) pool.push_back(element(f, c, k));
      }
      segments.resize(size_t(frames) * channels * 2);
      for (int f = 0; f < frames; ++f) {
        const size_t s = (size_t(f) * channels + c) * 2;
        if (src_cells[f].empty()) {
          segments[s] = channel_off;
          segments[s + 1] = int32_t(n_src_cells);
        } else {
          segments[s] = frame_off[f];
          segments[s + 1] = int32_t(src_cells[f].size());
        }
      }
    }
    for (int f = 0; f < frames; ++f)
      if (src_cells[f].empty()) plan.fallback_segments += channels;
  } else {
    // Pool in ascending element order, i.e. (frame, channel, cell): frame f's elements are contiguous.
    for (int f = 0; f < frames; ++f)
      for (int c = 0; c < channels; ++c)
        for (int32_t k : src_cells[f]) pool.push_back(element(f, c, k));
    if (scope == SlmOptions::Scope::global) {
      segments = {0, int32_t(pool.size())};
    } else {
      int32_t off = 0;
      for (int f = 0; f < frames; ++f) {
        const int32_t len = int32_t(src_cells[f].size()) * channels;
        if (len == 0) {
          segments.push_back(0);
          segments.push_back(int32_t(pool.size()));
          ++plan.fallback_segments;
        } else {
          segments.push_back(off);
          segments.push_back(len);
        }
        off += len;
      }
    }
  }
  plan.n_pool = int64_t(pool.size());
  plan.targets = upload_i32(ctx, targets, {plan.n_targets, 2}, "slm targets (" + what + ")");
  plan.segments = upload_i32(ctx, segments, {int64_t(segments.size() / 2), 2}, "slm segments (" + what + ")");
  plan.pool = upload_i32(ctx, pool, {plan.n_pool}, "slm pool (" + what + ")");
  return plan;
}

SlmPlan make_slm_plan(vk::Context& ctx, const SlmMasks& masks, int channels, SlmOptions::Scope scope) {
  SlmPlan plan;
  plan.latent_shape = {masks.frames, channels, masks.height, masks.width};
  plan.x0 = make_slm_index_plan(ctx, masks.x0_target, masks.x0_source, masks.frames, masks.height, masks.width,
                                channels, scope, "x0");
  plan.eps = make_slm_index_plan(ctx, masks.eps_target, masks.eps_source, masks.frames, masks.height, masks.width,
                                 channels, scope, "eps");
  return plan;
}

void apply_slm(vk::Recorder& rec, const Tensor& latent, const SlmIndexPlan& plan, const ops::RandomStream& rs) {
  ops::expect_dtype("apply_slm", "latent", latent, DType::f32);
  if (plan.n_targets == 0) return;
  if (latent.numel() != plan.latent_numel)
    throw Error("internal: apply_slm: latent " + latent.describe() + " does not match the plan's " +
                std::to_string(plan.latent_numel) + " elements");
  SamplePush p{uint32_t(plan.n_targets), uint32_t(rs.seed), uint32_t(rs.seed >> 32), rs.stream, uint32_t(rs.base),
               uint32_t(rs.base >> 32)};
  const ops::Grid g = ops::grid_1d(rec.context().caps(), plan.n_targets, 64);
  rec.dispatch(rec.context().pipelines().get("diffusion/slm_sample"),
               {latent.buffer(), plan.targets.buffer(), plan.segments.buffer(), plan.pool.buffer()}, &p, sizeof p,
               g.x, g.y, g.z, "slm_sample");
}

Tensor positions_to_replace(vk::Context& ctx, const SlmMasks& masks, int channels) {
  const int64_t hw = int64_t(masks.height) * masks.width;
  if (int64_t(masks.x0_target.size()) != masks.cells() || channels < 1)
    throw Error("internal: positions_to_replace: masks of " + std::to_string(masks.x0_target.size()) + " cells");
  std::vector<float> p(size_t(masks.cells() * channels));
  for (int64_t f = 0; f < masks.frames; ++f)
    for (int64_t c = 0; c < channels; ++c)
      for (int64_t k = 0; k < hw; ++k) p[size_t((f * channels + c) * hw + k)] = masks.x0_target[size_t(f * hw + k)] ? 1.0f : 0.0f;
  return Tensor::upload(ctx, HostTensor::from_f32({masks.frames, channels, masks.height, masks.width}, p));
}

ops::RandomStream slm_stream(uint64_t seed, bool eps, int round, int64_t latent_numel) {
  // A round draws at most latent_numel elements, so windows [round·numel, (round+1)·numel) never overlap.
  return ops::RandomStream{seed, eps ? kSlmStreamEps : kSlmStreamX0, uint64_t(round) * uint64_t(latent_numel)};
}

void apply_slm(vk::Recorder& rec, const Tensor& x0, const Tensor& eps, const SlmPlan& plan, uint64_t seed,
               int round) {
  if (x0.numel() != shape_numel(plan.latent_shape) || eps.numel() != shape_numel(plan.latent_shape))
    throw Error("internal: apply_slm: latents " + x0.describe() + " / " + eps.describe() + " do not match the plan " +
                shape_str(plan.latent_shape));
  apply_slm(rec, x0, plan.x0, slm_stream(seed, false, round, x0.numel()));
  apply_slm(rec, eps, plan.eps, slm_stream(seed, true, round, eps.numel()));
}

}  // namespace dvs::diffusion
