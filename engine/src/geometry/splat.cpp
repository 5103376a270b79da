#include "geometry/splat.hpp"

#include "geometry/splat_memory.hpp"

#include <algorithm>
#include <cstring>

#include "dvs/error.hpp"
#include "tensor/binding_split.hpp"
#include "tensor/dispatch.hpp"
#include "vk/context.hpp"
#include "vk/pipeline.hpp"
#include "vk/transfer.hpp"

namespace dvs::geometry {

namespace {

struct Push {  // splat_common.glsl
  uint32_t H, W, frame, flags;
  float src_k[4];
  float k_map[4];  // the target camera against the source's: fx_d/fx_s − 1, fy_d/fy_s − 1, cx_d − cx_s, cy_d − cy_s
  float t[12];     // rows 0..2 of T − I: the identity moves no point, exactly (splat_common.glsl says why)
};
static_assert(sizeof(Push) == 96);

struct ResolvePush {
  uint32_t H, W, frames;
};

constexpr uint32_t kKeepBehind = 1;

SplatLimits limits_of(const vk::Context& ctx) {
  const vk::DeviceCaps& c = ctx.caps();
  return {c.max_storage_buffer_range, c.max_memory_allocation_size, c.max_workgroup_count[0], c.max_workgroup_count[1],
          "device " + c.name + (c.forced_limits.any() ? " lowered by DVS_LIMITS" : "")};
}

void expect(const char* arg, const Tensor& t, const Shape& s) {
  ops::expect_shape("splat_render", arg, t, s);
  ops::expect_dtype("splat_render", arg, t, DType::f32);
}

}  // namespace

// The chunk splat_footprint sizes: as many frames as fit one binding and one allocation of the accumulation.
int SplatRenderer::frames_per_binding(const vk::Context& ctx, int height, int width) {
  return int(splat_footprint(65535, height, width, false, false, limits_of(ctx)).chunk_frames);
}

SplatRenderer::SplatRenderer(vk::Context& ctx, int height, int width, int max_frames, const SplatOptions& options)
    : ctx_(ctx), H_(height), W_(width), max_frames_(max_frames), options_(options) {
  if (height < 1 || width < 1 || max_frames < 1) throw Error("splat renderer: size and frame count must be positive");
  const SplatFootprint fp = splat_footprint(max_frames, height, width, options.mode == SplatMode::hard_point,
                                            options.atomics == SplatAtomics::float_atomics, limits_of(ctx));
  if (!fp.problem.empty()) throw Error(fp.problem);
  if (max_frames > fp.chunk_frames)
    throw Error("splat renderer: " + std::to_string(max_frames) + " frames of " + std::to_string(height) + "x" +
                std::to_string(width) + " exceed one storage binding or allocation; render in chunks of at most " +
                std::to_string(fp.chunk_frames) + " frames (render_clip does)");
  if (max_frames > 65535) throw Error("splat renderer: at most 65535 frames per dispatch");
  // Only on request: float atomics sum in whatever order the invocations run, so two renders of the same
  // input differ in the last bits, and that difference grows through the whole diffusion chain.
  float_atomics_ = options.atomics == SplatAtomics::float_atomics;
  if (float_atomics_ && !ctx.caps().float32_atomic_add)
    throw Error("splat renderer: float atomics were requested but this device has no float32 atomic add");
  const uint64_t pixels = uint64_t(max_frames) * uint64_t(height) * uint64_t(width);
  auto& a = ctx.allocator();
  framemax_ = a.allocate(uint64_t(max_frames) * 4, vk::MemoryUse::device, "splat frame max");
  if (options.mode == SplatMode::soft_bilinear) {
    accum_ = a.allocate(pixels * 16, vk::MemoryUse::device, "splat accumulation");
    if (!float_atomics_) keys_ = a.allocate(pixels * 4, vk::MemoryUse::device, "splat keys");
  } else {
    accum_ = a.allocate(pixels * 4, vk::MemoryUse::device, "z-buffer depth keys");
    keys_ = a.allocate(pixels * 4, vk::MemoryUse::device, "z-buffer point keys");
  }
}

void SplatRenderer::record(vk::Recorder& rec, const Tensor& rgb, const Tensor& depth, std::span<const glm::dmat4> transforms,
                           const Intrinsics& K_src, const Intrinsics& K_dst, const Tensor& render, const Tensor& mask) {
  const int64_t F = int64_t(transforms.size());
  if (F < 1 || F > max_frames_)
    throw Error("internal: splat_render: " + std::to_string(F) + " frames, renderer built for " + std::to_string(max_frames_));
  expect("depth", depth, {F, H_, W_});
  expect("rgb", rgb, {F, 3, H_, W_});
  expect("render", render, {F, 3, H_, W_});
  expect("mask", mask, {F, H_, W_});
  K_src.validate();
  K_dst.validate();

  std::vector<Push> push(static_cast<size_t>(F));
  for (int64_t f = 0; f < F; ++f) {
    Push& p = push[size_t(f)];
    // In double on the host, so that equal cameras give exact zeros.
    p = Push{uint32_t(H_), uint32_t(W_), uint32_t(f), 0,
             {float(K_src.fx), float(K_src.fy), float(K_src.cx), float(K_src.cy)},
             {float(K_dst.fx / K_src.fx - 1.0), float(K_dst.fy / K_src.fy - 1.0), float(K_dst.cx - K_src.cx),
              float(K_dst.cy - K_src.cy)},
             {}};
    if (options_.keep_points_behind_camera) p.flags |= kKeepBehind;
    const glm::dmat4& T = transforms[size_t(f)];
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) p.t[r * 4 + c] = float(T[c][r] - (r == c ? 1.0 : 0.0));
  }
  const ResolvePush rpush{uint32_t(H_), uint32_t(W_), uint32_t(F)};

  const uint64_t pixels = uint64_t(F) * uint64_t(H_) * uint64_t(W_);
  const uint32_t gx = ops::div_up(W_, 64), gy = uint32_t(H_);  // one frame per dispatch: (W/64, H) groups
  if (H_ > 65535 || gx > 65535) throw Error("splat renderer: image too large for one dispatch per frame");
  const ops::Grid g = ops::grid_1d(rec.context().caps(), int64_t(pixels), 64);
  auto& pipes = rec.context().pipelines();
  auto per_frame = [&](const vk::Pipeline& pipe, std::initializer_list<vk::Binding> b, const char* label,
                       uint32_t groups_x) {
    for (int64_t f = 0; f < F; ++f) rec.dispatch(pipe, b, &push[size_t(f)], sizeof(Push), groups_x, gy, 1, label);
  };

  if (options_.mode == SplatMode::hard_point) {
    vk::BufferView zkey = accum_.view().sub(0, pixels * 4), idkey = keys_.view().sub(0, pixels * 4);
    rec.fill_zero(zkey);
    rec.fill_zero(idkey);
    for (uint32_t pass = 0; pass < 2; ++pass) {
      uint32_t spec[1] = {pass};
      per_frame(pipes.get("render/splat_point", spec), {depth.buffer(), zkey, idkey},
                pass == 0 ? "splat_point_depth" : "splat_point_index", gx);
    }
    rec.dispatch(pipes.get("render/splat_point_resolve"), {rgb.buffer(), idkey, render.buffer(), mask.buffer()}, &rpush,
                 sizeof rpush, g.x, g.y, g.z, "splat_point_resolve");
    return;
  }

  vk::BufferView fmax = framemax_.view().sub(0, uint64_t(F) * 4);
  vk::BufferView accum = accum_.view().sub(0, pixels * 16);
  rec.fill_zero(fmax);
  rec.fill_zero(accum);
  per_frame(pipes.get("render/splat_depth_max"), {depth.buffer(), fmax}, "splat_depth_max", ops::div_up(W_, 64 * 16));
  if (float_atomics_) {
    per_frame(pipes.get("render/splat_forward_float"), {depth.buffer(), fmax, rgb.buffer(), accum}, "splat_forward_float", gx);
    uint32_t spec[1] = {0};
    rec.dispatch(pipes.get("render/splat_resolve", spec), {accum, accum, render.buffer(), mask.buffer()}, &rpush,
                 sizeof rpush, g.x, g.y, g.z, "splat_resolve");
  } else {
    vk::BufferView keys = keys_.view().sub(0, pixels * 4);
    rec.fill_zero(keys);
    per_frame(pipes.get("render/splat_min_cost"), {depth.buffer(), fmax, keys}, "splat_min_cost", gx);
    per_frame(pipes.get("render/splat_forward_fixed"), {depth.buffer(), fmax, rgb.buffer(), keys, accum},
              "splat_forward_fixed", gx);
    uint32_t spec[1] = {1};
    rec.dispatch(pipes.get("render/splat_resolve", spec), {accum, keys, render.buffer(), mask.buffer()}, &rpush,
                 sizeof rpush, g.x, g.y, g.z, "splat_resolve");
  }
}

HostTensor transforms_to_host(const Trajectory& t, int first, int count) {
  if (first < 0 || count < 0 || first + count > t.frames())
    throw Error("internal: transforms_to_host: frames [" + std::to_string(first) + ", " + std::to_string(first + count) +
                ") of a " + std::to_string(t.frames()) + "-frame trajectory");
  HostTensor h({count, 16}, DType::f32);
  float* out = h.as<float>();
  for (int i = 0; i < count; ++i) {
    const glm::dmat4& m = t.transforms[size_t(first + i)];
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) out[i * 16 + r * 4 + c] = float(m[c][r]);
  }
  return h;
}

RenderedClip render_clip(vk::Context& ctx, const HostTensor& rgb, const HostTensor& depth, const Trajectory& trajectory,
                         const Intrinsics& K, const SplatOptions& options) {
  if (depth.shape.size() != 3 || depth.dtype != DType::f32)
    throw Error("render: depth must be f32 [F,H,W], got " + std::string(dtype_name(depth.dtype)) + "[" + shape_str(depth.shape) + "]");
  const int64_t F = depth.shape[0], H = depth.shape[1], W = depth.shape[2];
  if (rgb.dtype != DType::f32 || rgb.shape != Shape{F, 3, H, W})
    throw Error("render: video must be f32 [" + shape_str({F, 3, H, W}) + "] to match the depth, got " +
                std::string(dtype_name(rgb.dtype)) + "[" + shape_str(rgb.shape) + "]");
  if (trajectory.frames() != F)
    throw Error("render: the trajectory has " + std::to_string(trajectory.frames()) + " poses for " + std::to_string(F) +
                " frames");
  if (K.width != W || K.height != H)
    throw Error("render: the intrinsics are for " + std::to_string(K.height) + "x" + std::to_string(K.width) +
                " (HxW) but the frames are " + std::to_string(H) + "x" + std::to_string(W) + " (use Intrinsics::scaled_to)");
  // Chunks of frames whose every buffer fits one binding and one allocation (rgb/render: 3 planes per frame,
  // below the accumulation's 4 words); a size whose one frame does not fit is refused here, before any upload.
  const SplatFootprint fp = splat_footprint(F, H, W, options.mode == SplatMode::hard_point,
                                            options.atomics == SplatAtomics::float_atomics, limits_of(ctx));
  if (!fp.problem.empty()) throw Error(fp.problem);
  int chunk = int(fp.chunk_frames);
  if (options.max_chunk_frames > 0) chunk = std::min(chunk, options.max_chunk_frames);
  SplatRenderer renderer(ctx, int(H), int(W), chunk, options);

  RenderedClip out{HostTensor({F, 3, H, W}, DType::f32), HostTensor({F, H, W}, DType::f32)};
  const size_t plane = size_t(H * W);
  int allocated_for = 0;
  Tensor t_rgb, t_depth, t_render, t_mask;
  vk::Recorder rec(ctx);
  for (int64_t first = 0; first < F; first += chunk) {
    int n = int(std::min<int64_t>(chunk, F - first));
    if (n != allocated_for) {  // the last, shorter chunk: the old buffers go first (the footprint holds one set)
      t_rgb = t_depth = t_render = t_mask = Tensor();
      t_rgb = Tensor::empty(ctx, {n, 3, H, W}, DType::f32, "render input video");
      t_depth = Tensor::empty(ctx, {n, H, W}, DType::f32, "render input depth");
      t_render = Tensor::empty(ctx, {n, 3, H, W}, DType::f32, "render output");
      t_mask = Tensor::empty(ctx, {n, H, W}, DType::f32, "render mask");
      allocated_for = n;
    }
    ctx.transfer().upload(t_rgb.buffer(), rgb.data.data() + size_t(first) * 3 * plane * 4, size_t(n) * 3 * plane * 4);
    ctx.transfer().upload(t_depth.buffer(), depth.data.data() + size_t(first) * plane * 4, size_t(n) * plane * 4);
    rec.begin();  // the transforms are push constants: one short recording per chunk
    renderer.record(rec, t_rgb, t_depth, std::span<const glm::dmat4>(trajectory.transforms).subspan(size_t(first), size_t(n)),
                    K, K, t_render, t_mask);
    rec.end();
    rec.submit();
    ctx.transfer().download(t_render.buffer(), out.render.data.data() + size_t(first) * 3 * plane * 4, size_t(n) * 3 * plane * 4);
    ctx.transfer().download(t_mask.buffer(), out.mask.data.data() + size_t(first) * plane * 4, size_t(n) * plane * 4);
  }
  return out;
}

}  // namespace dvs::geometry
