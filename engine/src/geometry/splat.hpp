// The forward splat renderer (GLSL compute, shaders/render/): lifts every RGB-D pixel of a frame to a 3-D
// point (X = z·K⁻¹(x, y, 1), OpenCV axes, integer pixel coordinates), moves it by the frame's transform T_i
// (trajectory.hpp), projects it into the target camera and splats it.
//
// Soft mode (default) = the official renderer (docs/design.md §6.3): bilinear splat into the four
// neighbours in a buffer padded by one pixel (floor/ceil/clamp exactly as the official code), weights
// divided by exp(50·log(1+clamp(z,0,1000)) / max over the frame of the same), Σw·rgb / Σw; holes are −1
// (RGB in [−1, 1]); mask = 1 where weight landed, 0 in holes. Accumulation is 32-bit fixed point by default
// (weights taken relative to the strongest contribution of each pixel, scaled by 2^16): integer atomics
// are order-independent, so the same input gives a bit-identical render on every run (a run is
// reproducible to the byte). It matches the float path to ~1e-4 (2e-5 on the analytic scenes), far below
// one 8-bit video level; a pixel would overflow only past 65536 full-strength contributions (a zoom-out
// by 256× in each direction). Float atomics (VK_EXT_shader_atomic_float) are an option, not the default:
// their summation order changes from run to run.
// Point mode: a hard z-buffer — each point goes to its nearest pixel and the nearest point wins.
// Points behind the target camera are dropped unless keep_points_behind_camera asks for the official
// behaviour (projected with flipped signs and the largest weight).
//
// Layouts (f32, contiguous): rgb [F,3,H,W] in [−1,1], depth [F,H,W] (metric, > 0), render [F,3,H,W],
// mask [F,H,W] in {0,1}; one 4×4 T_i per frame. Target size = source size.
//
// Typical use (what `dvs render` does; rgb is the decoded video as f32 [F,3,H,W] in [−1,1]):
//   HostTensor z = fit_depth_to_video(load_depth(depth_path, {DepthValues::disparity}), F, H, W, trim, name);
//   Intrinsics K = Intrinsics::official_default(W, H);                      // or the user's fx fy cx cy
//   Trajectory t = load_trajectory(spec, F, official_radius(centre_depth(z)));
//   RenderedClip r = render_clip(ctx, rgb, z, t, K);                        // render + mask
//   write_npy(dir / "mask.npy", r.mask);  write_trajectory_json(dir / "poses.json", t);
//   PointCloud pc = point_cloud_from_rgbd(rgb.as<float>(), z.as<float>(), H, W, K, 2);
//   write_trajectory_glb(dir / "scene.glb", t, &pc);
#pragma once
#include <span>
#include <vector>

#include "geometry/camera.hpp"
#include "geometry/trajectory.hpp"
#include "io/host_tensor.hpp"
#include "tensor/tensor.hpp"
#include "vk/memory.hpp"
#include "vk/recorder.hpp"

namespace dvs::geometry {

enum class SplatMode { soft_bilinear, hard_point };
enum class SplatAtomics { automatic, float_atomics, fixed_point };

struct SplatOptions {
  SplatMode mode = SplatMode::soft_bilinear;
  // automatic = fixed_point (deterministic); float_atomics only where the device has them, and only on request
  SplatAtomics atomics = SplatAtomics::automatic;
  bool keep_points_behind_camera = false;          // official behaviour (soft mode only)
  int max_chunk_frames = 0;                        // render_clip: frames per chunk (0 = as many as fit)
};

// Scratch buffers for up to max_frames frames of height × width, and the recording of one render.
class SplatRenderer {
 public:
  SplatRenderer(vk::Context& ctx, int height, int width, int max_frames, const SplatOptions& options = {});

  // Records the render of F ≤ max_frames frames (F = transforms.size()). K_src unprojects the input, K_dst
  // projects into the target. The transforms go into push constants (one dispatch per frame and pass), so a
  // recording is tied to them: record again for another trajectory.
  void record(vk::Recorder& rec, const Tensor& rgb, const Tensor& depth, std::span<const glm::dmat4> transforms,
              const Intrinsics& K_src, const Intrinsics& K_dst, const Tensor& render, const Tensor& mask);

  bool uses_float_atomics() const { return float_atomics_; }
  int max_frames() const { return max_frames_; }
  // Frames of height × width whose buffers fit one storage binding and one allocation of this device (≥ 1;
  // geometry/splat_memory.hpp sizes them).
  static int frames_per_binding(const vk::Context& ctx, int height, int width);

 private:
  vk::Context& ctx_;
  int H_, W_, max_frames_;
  SplatOptions options_;
  bool float_atomics_ = false;
  vk::Buffer framemax_, accum_, keys_;
};

// Row-major [count,16] f32 of transforms[first, first+count).
HostTensor transforms_to_host(const Trajectory& t, int first, int count);

struct RenderedClip {
  HostTensor render;  // [F,3,H,W] f32 in [−1,1], holes −1
  HostTensor mask;    // [F,H,W] f32, 1 = visible
};

// Renders a whole clip held on the host, in chunks of frames that fit the device's binding limits
// (49 frames at 576×1024 go through in 4 chunks). rgb [F,3,H,W] f32 in [−1,1], depth [F,H,W] f32 metric
// depth; trajectory.frames() must equal F. This is the entry point for `dvs render`.
RenderedClip render_clip(vk::Context& ctx, const HostTensor& rgb, const HostTensor& depth, const Trajectory& trajectory,
                         const Intrinsics& K, const SplatOptions& options = {});

}  // namespace dvs::geometry
